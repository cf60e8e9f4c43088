//! The `hilcam` command line: clap parses, each subcommand lives in its own file.

pub mod demo;
pub mod recv;
pub mod render;
pub mod replay;
pub mod send;
pub mod sensor;
pub mod serve;
pub mod signal;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

#[cfg(feature = "lab")]
use hilcam_lab::cli::{bench, brdf, fold, model};

#[derive(Parser, Debug)]
#[command(name = "hilcam", version, about = "Hardware-in-the-loop camera simulator for spacecraft navigation")]
pub struct Cli {
    /// Log filter (tracing env-filter syntax), e.g. `info`, `hilcam_core=debug`. Lines are
    /// coloured only on a terminal, never with NO_COLOR set.
    #[arg(long, global = true, default_value = "info", env = "HILCAM_LOG")]
    pub log: String,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// The whole loop with no hardware: pty pose source → server → loopback TCP client.
    Demo(demo::DemoArgs),
    /// Run the real-time server: poses in (serial/CAN), frames out (TCP, files).
    Serve(serve::ServeArgs),
    /// Render one frame of a scene file to an image file.
    Render(render::RenderArgs),
    /// Benchmarks: ratios measured side by side in one run.
    #[cfg(feature = "lab")]
    Bench(bench::BenchArgs),
    /// Print the version and exit.
    Version,
    /// Apply a camera preset's sensor model to a radiance image (.pfm).
    Sensor(sensor::SensorArgs),
    /// Replay a trajectory file as live pose messages (serial, SocketCAN or slcan).
    Send(send::SendArgs),
    /// Receive a frame stream: verify CRCs, save frames, print rate, gaps and latency.
    Recv(recv::RecvArgs),
    /// Tabulate and plot the BRDF models (gold polyimide) and their directional albedo.
    #[cfg(feature = "lab")]
    Brdf(brdf::BrdfArgs),
    /// Fold planes: generate at the paper's levels, measure E_PLANE / Var.
    #[cfg(feature = "lab")]
    Fold(fold::FoldArgs),
    /// Generate the shipped models (the Jason-like satellite).
    #[cfg(feature = "lab")]
    Model(model::ModelArgs),
    /// Render a trajectory offline to image files (resumable; shards for clusters).
    Replay(replay::ReplayArgs),
}

/// Colour in log lines only on a terminal, and never with `NO_COLOR` set (no-color.org):
/// a log redirected to a file or a pipe stays plain text.
fn log_colour() -> bool {
    use std::io::IsTerminal;
    std::io::stderr().is_terminal() && std::env::var_os("NO_COLOR").is_none_or(|v| v.is_empty())
}

pub fn main() -> ExitCode {
    let cli = Cli::parse();
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::new(&cli.log))
        .with_writer(std::io::stderr)
        .with_ansi(log_colour())
        .init();
    if writes_for_a_pipe(&cli.command) {
        die_quietly_on_closed_pipe();
    }
    let result: anyhow::Result<()> = match cli.command {
        Command::Render(a) => render::run(a),
        Command::Demo(a) => demo::run_cli(a),
        Command::Serve(a) => serve::run_cli(a),
        #[cfg(feature = "lab")]
        Command::Bench(a) => bench::run(a),
        Command::Version => {
            println!("hilcam {}", env!("CARGO_PKG_VERSION"));
            Ok(())
        }
        Command::Sensor(args) => sensor::run(args),
        Command::Send(args) => send::run(args),
        Command::Recv(args) => recv::run(args),
        #[cfg(feature = "lab")]
        Command::Brdf(args) => brdf::run(args),
        #[cfg(feature = "lab")]
        Command::Fold(args) => fold::run(args),
        #[cfg(feature = "lab")]
        Command::Model(args) => model::run(args),
        Command::Replay(args) => replay::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", error_chain(&e));
            ExitCode::FAILURE
        }
    }
}

/// Subcommands whose output goes to a terminal or a pipe and that hold no socket: they
/// end quietly when the pipe closes (`hilcam render … | head -1`), as Unix tools do.
/// `serve`, `send`, `recv`, `replay` and `demo` keep Rust's ignored SIGPIPE, so a closed
/// connection is an error they count and report, not a kill.
fn writes_for_a_pipe(c: &Command) -> bool {
    match c {
        Command::Render(_) | Command::Version | Command::Sensor(_) => true,
        #[cfg(feature = "lab")]
        Command::Bench(_) | Command::Brdf(_) | Command::Fold(_) | Command::Model(_) => true,
        _ => false,
    }
}

/// The default SIGPIPE action (terminate), which Rust's runtime replaces with "ignore":
/// without it a closed stdout makes `println!` panic ("failed printing to stdout").
fn die_quietly_on_closed_pipe() {
    #[cfg(unix)]
    // SAFETY: setting a signal's disposition to its default before any thread is started.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

/// The error and its causes, `: `-separated, leaving out a cause whose text the message
/// already quotes (library errors name their cause in their own text, so that a log line
/// is complete; `{:#}` would print it twice).
fn error_chain(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in e.chain() {
        let msg = cause.to_string();
        if out.contains(&msg) {
            continue;
        }
        if !out.is_empty() {
            out.push_str(": ");
        }
        out.push_str(&msg);
    }
    out
}

/// A run's total Monte Carlo noise report (serve and replay print it at the end).
pub fn mc_noise_total(above: u64, lit: u64, k: f64) -> String {
    format!(
        "Monte Carlo noise: {above} of {lit} lit pixels ({:.2} %) above {k} × the camera's temporal noise",
        100.0 * above as f64 / lit.max(1) as f64
    )
}

/// `--sensor-k`: a fraction of the camera's temporal noise in (0, 10].
pub fn parse_sensor_k(s: &str) -> Result<f32, String> {
    hilcam_core::render::integrator::QualityGoal::parse_k(s)
}

#[cfg(test)]
mod tests {
    use super::error_chain;

    #[test]
    fn a_cause_quoted_by_its_error_is_printed_once() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "No such file or directory (os error 2)");
        let e = hilcam_scene_error(io);
        assert_eq!(error_chain(&e), "scenes/x.toml: No such file or directory (os error 2)");
        let ctx = anyhow::anyhow!("inner cause").context("while loading");
        assert_eq!(error_chain(&ctx), "while loading: inner cause");
    }

    fn hilcam_scene_error(source: std::io::Error) -> anyhow::Error {
        hilcam_core::scene::file::SceneError::Io { path: "scenes/x.toml".into(), source }.into()
    }
}
