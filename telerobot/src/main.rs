//! The `telerobot` binary: parses arguments, sets up logging and Ctrl-C, calls [`telerobot::cli`].

use std::process::ExitCode;

use clap::Parser;
use telerobot::cli::{Cli, Command};

fn main() -> ExitCode {
    let cli = Cli::parse();
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_writer(std::io::stderr)
        // Colour only on a terminal: a log file or a pipe gets plain text.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    let result = match &cli.command {
        Command::GenCert(args) => telerobot::cli::gen_cert(args, &mut std::io::stdout()),
        Command::Run(args) => {
            let shutdown = rt::Shutdown::new();
            match shutdown.on_signals() {
                Ok(()) => telerobot::cli::run(args, shutdown),
                Err(e) => Err(anyhow::anyhow!("cannot watch for Ctrl-C: {e}")),
            }
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("telerobot: {}", rt::exit::message(e.as_ref()));
            ExitCode::FAILURE
        }
    }
}
