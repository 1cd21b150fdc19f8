//! The `demo` binary: parses arguments, sets up logging and Ctrl-C, calls [`demo::cli::run_cmd`].

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let cli = demo::cli::Cli::parse();
    demo::init_logging();
    let shutdown = rt::Shutdown::new();
    let result = shutdown
        .on_signals()
        .map_err(|e| anyhow::anyhow!("cannot watch for Ctrl-C: {e}"))
        .and_then(|()| demo::cli::run_cmd(&cli, shutdown.clone(), &mut std::io::stdout()));
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("demo: {}", rt::exit::message(e.as_ref()));
            ExitCode::FAILURE
        }
    }
}
