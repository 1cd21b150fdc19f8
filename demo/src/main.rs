//! The `demo` binary: parses arguments, sets up logging and Ctrl-C, calls [`demo::cli::run_cmd`].

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let cli = demo::cli::Cli::parse();
    // The demo's stdout is its report: by default it logs only warnings, and the safety layer's
    // per-episode events (counted in the report) not at all. RUST_LOG overrides.
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| {
                tracing_subscriber::EnvFilter::new("warn,operator::safety=error")
            }),
        )
        .with_writer(std::io::stderr)
        // Colour only on a terminal: a log file or a pipe gets plain text.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
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
