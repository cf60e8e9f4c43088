//! The `hilcam` command line: clap parses, each subcommand lives in its own file.

use clap::{Parser, Subcommand};
use std::process::ExitCode;

pub mod fold;
pub mod model;

#[derive(Parser, Debug)]
#[command(
    name = "hilcam",
    version,
    about = "Hardware-in-the-loop camera simulator for spacecraft navigation"
)]
pub struct Cli {
    /// Log filter (tracing env-filter syntax), e.g. `info`, `hilcam=debug`.
    #[arg(long, global = true, default_value = "info", env = "HILCAM_LOG")]
    pub log: String,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Print the version and exit (placeholder until real subcommands land).
    Version,
    /// Fold planes: generate at the paper's levels, measure E_PLANE / Var.
    Fold(fold::FoldArgs),
    /// Generate the shipped models (the Jason-like satellite).
    Model(model::ModelArgs),
}

pub fn main() -> ExitCode {
    let cli = Cli::parse();
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::new(&cli.log))
        .with_writer(std::io::stderr)
        .init();
    let result: anyhow::Result<()> = match cli.command {
        Command::Version => {
            println!("hilcam {}", env!("CARGO_PKG_VERSION"));
            Ok(())
        }
        Command::Fold(args) => fold::run(args),
        Command::Model(args) => model::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
