//! `hilcam model satellite`: (in progress)
use clap::{Args, Subcommand};
#[derive(Args, Debug)]
pub struct ModelArgs {
    #[command(subcommand)]
    pub command: ModelCommand,
}
#[derive(Subcommand, Debug)]
pub enum ModelCommand {
    Satellite,
}
pub fn run(_args: ModelArgs) -> anyhow::Result<()> {
    Ok(())
}
