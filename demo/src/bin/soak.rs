//! The `soak` binary: parses arguments, sets up logging and Ctrl-C, calls
//! [`demo::soak::cmd::run_cmd`]. Ctrl-C ends the run early with its rows and verdict written.

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let cli = demo::soak::cmd::SoakCli::parse();
    demo::init_logging();
    let shutdown = rt::Shutdown::new();
    let result = shutdown
        .on_signals()
        .map_err(|e| anyhow::anyhow!("cannot watch for Ctrl-C: {e}"))
        .and_then(|()| {
            demo::soak::cmd::run_cmd(
                &cli,
                shutdown.clone(),
                Box::new(std::io::stdout()),
                &mut std::io::stdout(),
            )
        });
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("soak: {}", rt::exit::message(e.as_ref()));
            ExitCode::FAILURE
        }
    }
}
