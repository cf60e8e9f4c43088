//! The `hilcam` command line: clap parses, each subcommand lives in its own file.

pub mod sensor;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

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
    /// Apply a camera preset's sensor model to a radiance image (.pfm).
    Sensor(sensor::SensorArgs),
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
        Command::Sensor(args) => sensor::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
