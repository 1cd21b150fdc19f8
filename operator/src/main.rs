//! The `operator` binary: parses arguments, sets up logging and Ctrl-C, calls [`operator::cli`].

use std::process::ExitCode;

use clap::Parser;
use operator::cli::{Cli, Command};

fn main() -> ExitCode {
    let cli = Cli::parse();
    let default_filter = "info";
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default_filter)),
        )
        .with_writer(std::io::stderr)
        // Colour only on a terminal: a log file or a pipe gets plain text.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    let mut out = std::io::stdout();
    let shutdown = rt::Shutdown::new();
    let result = match &cli.command {
        Command::Devices(args) => {
            operator::cli::devices(args, &mut out).map(|()| ExitCode::SUCCESS)
        }
        Command::GenCert(args) => {
            operator::cli::gen_cert(args, &mut out).map(|()| ExitCode::SUCCESS)
        }
        Command::Run(args) => with_signals(&shutdown)
            .and_then(|()| operator::cli::run(args, shutdown.clone(), &mut out)),
    };
    result.unwrap_or_else(|e| {
        eprintln!("operator: {}", rt::exit::message(e.as_ref()));
        ExitCode::FAILURE
    })
}

/// Ctrl-C and SIGTERM stop the run (it still reports).
fn with_signals(shutdown: &rt::Shutdown) -> anyhow::Result<()> {
    shutdown
        .on_signals()
        .map_err(|e| anyhow::anyhow!("cannot watch for Ctrl-C: {e}"))
}
