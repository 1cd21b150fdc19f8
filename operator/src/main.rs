//! The `operator` binary: parses arguments, sets up logging, calls [`operator::cli`].

use std::process::ExitCode;

use clap::Parser;
use operator::cli::{Cli, Command};

fn main() -> ExitCode {
    let cli = Cli::parse();
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_writer(std::io::stderr)
        .init();
    let mut out = std::io::stdout();
    let result = match &cli.command {
        Command::Devices(args) => {
            operator::cli::devices(args, &mut out).map(|()| ExitCode::SUCCESS)
        }
        Command::Run(args) => operator::cli::run(args, &mut out),
        Command::GenCert(args) => {
            operator::cli::gen_cert(args, &mut out).map(|()| ExitCode::SUCCESS)
        }
    };
    result.unwrap_or_else(|e| {
        eprintln!("operator: {e:#}");
        ExitCode::FAILURE
    })
}
