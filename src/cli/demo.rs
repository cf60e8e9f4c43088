//! `hilcam demo`: the whole loop on one machine with no hardware and no config.
//!
//! A built-in pose source replays the shipped fly-around over a real pseudo-terminal
//! serial pair into the server; the server renders the shipped satellite at the
//! navigation camera's geometry and streams over loopback TCP to a built-in client,
//! which writes the frames and a latency summary. With `--gige` the server is also a
//! GigE Vision camera (docs/gige.md) that Aravis can watch, until Ctrl-C.

use anyhow::{Context, bail};
use hilcam_core::link::send::{SendOptions, SerialWriter, send_trajectory};
use hilcam_core::pose::trajectory::Trajectory;
use hilcam_core::serve::config::{GovernorConfig, OutputSection, RenderOverrides};
use hilcam_core::serve::config::{InputConfig, MetricsSection, SerialInput, ServeConfig, StreamSection, TriggerConfig};
use hilcam_core::serve::governor::Policy;
use hilcam_core::serve::scheduler::TriggerMode;
use hilcam_core::serve::{Embed, run};
use hilcam_core::sink::gige::GigeConfig;
use hilcam_core::sink::gige::gvcp::GVCP_PORT;
use hilcam_core::sink::{ImageFormat, RecvOptions, receive};
use serialport::SerialPort;
use std::net::{Ipv4Addr, SocketAddr};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

#[derive(clap::Args, Debug)]
pub struct DemoArgs {
    /// Frames to receive before stopping.
    #[arg(long, default_value_t = 8)]
    pub frames: u64,
    /// Where the client writes the frames.
    #[arg(long, default_value = "out/demo")]
    pub out: PathBuf,
    /// Frame rate of the server (fixed-rate governor keeps each frame in budget).
    #[arg(long, default_value_t = 2.0)]
    pub rate: f64,
    /// Also be a GigE Vision camera (watch it with Aravis); runs until Ctrl-C or --duration.
    #[arg(long)]
    pub gige: bool,
    /// The GigE Vision camera's address (any 127.x.y.z; a NIC's address to reach it from a board).
    #[arg(long, default_value = "127.0.0.1", requires = "gige")]
    pub gige_address: Ipv4Addr,
    /// Its GVCP port (Aravis only talks to 3956; 0 = any free port, for other clients).
    #[arg(long, alias = "port", default_value_t = GVCP_PORT, requires = "gige")]
    pub gige_port: u16,
    /// With --gige: stop after this many seconds instead of at Ctrl-C.
    #[arg(long, requires = "gige")]
    pub duration: Option<f64>,
}

/// The repository's `scenes/` folder: next to the working directory, or the source tree.
fn assets_root() -> anyhow::Result<PathBuf> {
    for root in [PathBuf::from("."), PathBuf::from(env!("CARGO_MANIFEST_DIR"))] {
        if root.join("scenes/satellite.toml").is_file() {
            return Ok(root);
        }
    }
    bail!("scenes/satellite.toml not found in the working directory or in {}", env!("CARGO_MANIFEST_DIR"))
}

pub fn run_cli(a: DemoArgs) -> anyhow::Result<()> {
    let rt = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build()?;
    rt.block_on(demo(a))
}

async fn demo(a: DemoArgs) -> anyhow::Result<()> {
    // SIGINT/SIGTERM/SIGHUP stop the demo cleanly (server first, then the pty's writer).
    let shutdown = super::signal::stop_on_signals(super::signal::Again::Ignore)?;
    let root = assets_root()?;
    std::fs::create_dir_all(&a.out).with_context(|| a.out.display().to_string())?;
    // A pseudo-terminal pair stands in for the bench's serial cable.
    let (master, slave) = serialport::TTYPort::pair().context("creating a pseudo-terminal pair")?;
    let device = slave.name().context("pty has no name")?;
    println!("demo: serial link {device} (pty), scene scenes/satellite.toml, {} frames at {} Hz", a.frames, a.rate);
    let gige = if a.gige { Some(gige_config(a.gige_address, a.gige_port)?) } else { None };

    let cfg = ServeConfig {
        scene: root.join("scenes/satellite.toml"),
        width: None,
        input: InputConfig::Serial(SerialInput { device: device.clone(), baud: 921_600 }),
        trigger: TriggerConfig { mode: TriggerMode::Rate, rate_hz: Some(a.rate), extrapolate: true },
        governor: GovernorConfig { policy: Policy::FixedRate, budget_ms: None },
        render: RenderOverrides::default(),
        stream: StreamSection { listen: "127.0.0.1:0".parse()?, ..Default::default() },
        record: None,
        metrics: MetricsSection { listen: None, print_interval_s: 2.0 },
        output: OutputSection { gige: gige.clone(), ..Default::default() },
        live: Default::default(),
        cameras: Vec::new(),
    };
    cfg.validate().map_err(|(f, m)| anyhow::anyhow!("{f}: {m}"))?;

    let (ready_tx, ready_rx) = tokio::sync::oneshot::channel();
    let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
    let server = tokio::spawn(run(cfg, Embed { ready: Some(ready_tx), ..Default::default() }, stop_rx));
    let info = match ready_rx.await {
        Ok(i) => i,
        Err(_) => return Err(server.await?.err().unwrap_or_else(|| anyhow::anyhow!("server did not start"))),
    };

    // The client connects first so that it sees every frame from the first on.
    let opts =
        RecvOptions { out_dir: Some(a.out.clone()), count: Some(a.frames), format: ImageFormat::Png, progress: None };
    let client = tokio::spawn(receive(info.stream, opts));
    tokio::time::sleep(Duration::from_millis(100)).await;

    if let Some(g) = &gige {
        announce_gige(SocketAddr::from((g.address, g.gvcp_port)));
    }

    // The pose source: the fly-around (600 s) at 30× speed, or 5× (2 minutes) for a
    // GigE Vision client to watch; poses at 60 Hz × speed / 30.
    let speed = if a.gige { 5.0 } else { 30.0 };
    let samples: Arc<[_]> = Trajectory::load(root.join("scenes/trajectories/flyaround.csv"))?.into();
    let (send_stop_tx, send_stop_rx) = tokio::sync::oneshot::channel::<()>();
    let sender = tokio::spawn(send_trajectory(
        samples,
        SendOptions { rate_hz: None, speed },
        Box::new(SerialWriter::new(master, "demo pty")),
        send_stop_rx,
    ));

    let client_abort = client.abort_handle();
    let (received, interrupted) = if a.gige {
        // The camera serves until Ctrl-C (the normal end here) or --duration; the TCP
        // client takes its frames meanwhile.
        let until = async {
            match a.duration {
                Some(s) => tokio::time::sleep(Duration::from_secs_f64(s.max(0.0))).await,
                None => std::future::pending().await,
            }
        };
        tokio::select! {
            _ = shutdown.wait() => println!("demo: {}, stopping", super::signal::cause(&shutdown)),
            _ = until => println!("demo: --duration reached, stopping"),
        }
        let got = if client.is_finished() { Some(Ok(client.await)) } else { None };
        (got, None)
    } else {
        tokio::select! {
            r = tokio::time::timeout(Duration::from_secs(50), client) => (Some(r), None),
            _ = shutdown.wait() => (None, Some(super::signal::cause(&shutdown))),
        }
    };
    client_abort.abort();
    // Stop the server before the pose source, so the pty is not pulled from under it.
    let _ = stop_tx.send(());
    let report = server.await??;
    let _ = send_stop_tx.send(());
    let sent = sender.await?.context("pose sender")?;
    drop(slave);
    if let Some(name) = interrupted {
        super::serve::print_report(&report);
        bail!("stopped by {name} before {} frames were received; frames so far are in {}", a.frames, a.out.display());
    }
    let summary = match received {
        Some(Ok(r)) => r??,
        _ if a.gige => {
            println!("poses sent {} over the pty", sent.poses);
            super::serve::print_report(&report);
            println!("client: fewer than {} frames over TCP before the stop; nothing written", a.frames);
            return Ok(());
        }
        _ => bail!("no {} frames within 50 s", a.frames),
    };

    println!("poses sent {} over the pty", sent.poses);
    super::serve::print_report(&report);
    println!(
        "client: {} frames, {:.1} frames/s, sequence gaps {}, CRC errors {}",
        summary.frames, summary.fps, summary.gaps, summary.payload_crc_errors
    );
    let ms = |ns: u64| ns as f64 / 1e6;
    let l = &summary.pose_to_recv;
    println!(
        "client latency pose arrival → frame received: p50 {:.1} ms, p95 {:.1} ms, p99 {:.1} ms",
        ms(l.p50_ns),
        ms(l.p95_ns),
        ms(l.p99_ns)
    );
    write_summary(&a.out, &summary)?;
    let preview = write_preview(&a.out, summary.seqs.last().copied())?;
    println!(
        "frames written to {}/ (16-bit PNG holding the sensor's DN; {} is an 8-bit preview; latency summary in summary.txt)",
        a.out.display(),
        preview.display()
    );
    Ok(())
}

/// The `[output.gige]` of the demo camera. Port 0 is resolved here so the address can
/// be announced; a taken port is refused with what to do instead.
fn gige_config(address: Ipv4Addr, port: u16) -> anyhow::Result<GigeConfig> {
    let probe = std::net::UdpSocket::bind((address, port)).map_err(|e| {
        anyhow::anyhow!(
            "--gige: cannot bind UDP {address}:{port}: {e}. Another GigE Vision camera (or hilcam) may hold it: \
             pick another loopback address (--gige-address 127.0.0.2; Aravis only talks to port 3956), or \
             --gige-port 0 for any free port (clients other than Aravis). Ports below 1024 need root or \
             `setcap cap_net_bind_service=+ep` on the binary"
        )
    })?;
    let gvcp_port = probe.local_addr()?.port();
    drop(probe);
    Ok(GigeConfig { address, gvcp_port, serial: "HILCAMDEMO".into(), ..GigeConfig::default() })
}

/// Where the camera is and the commands that watch it.
fn announce_gige(at: SocketAddr) {
    let ip = at.ip();
    println!("demo: GigE Vision camera on {at} (GVCP); watch it with");
    println!("  arv-tool-0.8 -a {ip} control Width Height PixelFormat ExposureTime");
    println!("  arv-camera-test-0.8 -n {ip} --no-packet-socket -a --gv-packet-delay=20000");
    if on_path("arv-viewer-0.8") {
        println!("  arv-viewer-0.8        (needs a display; lists the cameras its discovery reaches)");
    }
    if at.port() != GVCP_PORT {
        println!("  (Aravis only talks to port {GVCP_PORT}: these need --gige-port {GVCP_PORT})");
    }
    if !on_path("arv-tool-0.8") {
        println!("  (Aravis is not installed: scripts/setup-aravis.sh)");
    }
    println!("demo: Ctrl-C stops it");
}

fn on_path(tool: &str) -> bool {
    std::env::var_os("PATH").is_some_and(|p| std::env::split_paths(&p).any(|d| d.join(tool).is_file()))
}

fn write_summary(dir: &Path, s: &hilcam_core::sink::RecvSummary) -> anyhow::Result<()> {
    let ms = |ns: u64| ns as f64 / 1e6;
    let l = &s.pose_to_recv;
    let text = format!(
        "frames {}\nfps {:.2}\ngaps {}\ncrc_errors {}\npose_to_recv_ms p50 {:.2} p95 {:.2} p99 {:.2} max {:.2}\n",
        s.frames,
        s.fps,
        s.gaps,
        s.payload_crc_errors,
        ms(l.p50_ns),
        ms(l.p95_ns),
        ms(l.p99_ns),
        ms(l.max_ns)
    );
    std::fs::write(dir.join("summary.txt"), text)?;
    Ok(())
}

/// An 8-bit, contrast-stretched copy of the last frame for people to look at (the frames
/// themselves hold raw 10/12-bit DN, which look black in most viewers).
fn write_preview(dir: &Path, last: Option<u64>) -> anyhow::Result<PathBuf> {
    let Some(seq) = last else { bail!("no frame received") };
    let src = dir.join(hilcam_core::sink::recorder::frame_file_name(seq, ImageFormat::Png));
    let img = image::open(&src).with_context(|| src.display().to_string())?.into_luma16();
    let mut v: Vec<u16> = img.as_raw().clone();
    v.sort_unstable();
    let white = f32::from(v[(v.len() as f64 * 0.999) as usize].max(1));
    let out = image::GrayImage::from_fn(img.width(), img.height(), |x, y| {
        image::Luma([((f32::from(img.get_pixel(x, y)[0]) / white).min(1.0).powf(1.0 / 2.2) * 255.0) as u8])
    });
    let path = dir.join("preview.png");
    out.save(&path).with_context(|| path.display().to_string())?;
    Ok(path)
}
