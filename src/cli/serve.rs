//! `hilcam serve`: run the real-time server from a config file until Ctrl-C, SIGTERM or
//! SIGHUP ([`super::signal`]; all three stop it cleanly: current frame finished, clients
//! closed on a frame boundary, session file ended, summary printed, exit 0).

use hilcam_core::serve::config::{RecordSection, ServeConfig};
use hilcam_core::serve::{Embed, ServeReport, run};
use hilcam_core::sink::ImageFormat;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct ServeArgs {
    /// Server configuration (TOML; see config/serve-*.toml).
    #[arg(long, short)]
    pub config: PathBuf,
    /// Record a session file (poses received, frames rendered; docs/session.md), as
    /// `[record] session` does; re-render it with `hilcam replay --session`.
    #[arg(long, value_name = "FILE")]
    pub record_session: Option<PathBuf>,
}

pub fn run_cli(a: ServeArgs) -> anyhow::Result<()> {
    let mut cfg = ServeConfig::load(&a.config)?;
    if let Some(path) = a.record_session {
        let r = cfg.record.get_or_insert(RecordSection { dir: None, session: None, format: ImageFormat::Png });
        r.session = Some(path);
    }
    let shutdown = super::signal::stop_on_signals(super::signal::Again::Ignore)?;
    let rt = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build()?;
    let report = rt.block_on(async {
        let stop = async move {
            shutdown.wait().await;
            tracing::info!("{}: finishing the current frame, closing clients", super::signal::cause(&shutdown));
        };
        run(cfg, Embed::default(), stop).await
    })?;
    print_report(&report);
    if let Some(s) = &report.session {
        println!("session {}: {} lines, {} dropped", s.path.display(), s.written, s.dropped);
    }
    Ok(())
}

pub fn print_report(r: &ServeReport) {
    let s = &r.scheduler;
    println!(
        "frames {} (late {}, degraded {}, renderer-busy skips {}), poses accepted {} rejected {} superseded {}, client drops {}",
        s.frames, s.late, s.degraded, s.skipped_busy, r.poses_accepted, r.poses_rejected, s.superseded, r.client_drops
    );
    println!("render time p50 {:.1} ms, p99 {:.1} ms", s.render_p50_ms, s.render_p99_ms);
    if s.mc_lit_pixels > 0 {
        println!("{}", super::mc_noise_total(s.mc_above_bound, s.mc_lit_pixels, s.mc_k));
    }
    if let Some((p50, p95, p99)) = r.latency_ms {
        println!("latency pose arrival → last byte: p50 {p50:.1} ms, p95 {p95:.1} ms, p99 {p99:.1} ms");
    }
}
