//! Issue 37: the SFNC features a GenICam client expects, read and written through
//! Aravis (`arv-tool-0.8`, its Python bindings and chunk parser) and through the GenICam
//! committee's reference GenApi (PyPI `genicam`), which also validates the XML; and
//! discovery the way Aravis 0.8 does it (a limited broadcast on each interface, in a
//! private network namespace: it broadcasts on every interface it has).

use crate::gige::{Rig, camera, python_client, run};
use crate::netns;
use hilcam_core::frame::{Frame, FrameFlags, FrameMeta, PixelFormat};
use hilcam_core::metrics::Registry;
use hilcam_core::render::film::Pixels;
use hilcam_core::render::integrator::Spp;
use hilcam_core::sink::gige::{GigeConfig, GigeDevice};
use std::net::Ipv4Addr;
use std::path::PathBuf;
use std::sync::Arc;

fn control(ip: Ipv4Addr, kv: &[&str]) -> Vec<String> {
    let mut v = vec!["-a".to_string(), ip.to_string(), "control".to_string()];
    v.extend(kv.iter().map(|s| s.to_string()));
    v
}

/// A 64×48 frame that integrated `integration_s`.
fn frame(integration_s: f32) -> Arc<hilcam_core::frame::EncodedFrame> {
    let meta = FrameMeta {
        frame_seq: 1,
        pose_seq: 1,
        pose_t_ns: 1,
        pose_arrival_unix_ns: 0,
        emit_unix_ns: 0,
        width: 64,
        height: 48,
        format: PixelFormat::Mono16,
        bit_depth: 12,
        spp: Spp::from_milli(1000),
        depth: 1,
        integration_s,
        line_time_ns: 0,
        flags: FrameFlags::default(),
    };
    Arc::new(Frame::new(meta, Pixels::Mono16 { data: vec![0; 64 * 48], bits: 12 }).unwrap().encode())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn aravis_reads_exposure_time_as_the_sensor_integrates_it() {
    let ip = Ipv4Addr::new(127, 0, 0, 64);
    let cfg = GigeConfig { address: ip, ..GigeConfig::default() };
    let device = GigeDevice::start(&cfg, camera(64, 48), Registry::new()).await.unwrap();
    // Auto-exposure on (the camera starts in it); the sensor integrated 26 µs.
    device.publish(&frame(26e-6));
    let read = |kv: &'static [&'static str]| run("arv-tool-0.8", control(ip, kv));
    let (ok, out) = read(&["ExposureAuto", "ExposureTime", "ExposureMode=Timed", "ExposureMode"]).await;
    assert!(ok && out.contains("ExposureAuto = Continuous") && out.contains("ExposureMode = Timed"), "{out}");
    assert!(out.contains("ExposureTime = 26"), "auto: what the sensor integrates, not the configured 1000 µs\n{out}");
    let (ok, out) = read(&["ExposureAuto=Off", "ExposureTime"]).await;
    assert!(ok && out.contains("ExposureTime = 26"), "auto → Off keeps the auto-exposure's time\n{out}");
    let (ok, out) = read(&["ExposureTime=50", "ExposureTime"]).await;
    assert!(ok && out.contains("ExposureTime = 50"), "{out}");
    device.publish(&frame(31e-6));
    let (ok, out) = read(&["ExposureAuto=Continuous", "ExposureTime"]).await;
    assert!(ok && out.contains("ExposureTime = 31"), "back in auto: not the last manual 50 µs\n{out}");
    device.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn aravis_reads_and_writes_the_sfnc_features_and_chunks() {
    let ip = Ipv4Addr::new(127, 0, 0, 65);
    let rig = Rig::start(ip, 320, 240).await;
    let (ok, out) = run("arv-tool-0.8", control(ip, &["DeviceFirmwareVersion", "WidthMax", "TLParamsLocked"])).await;
    let firmware = format!("DeviceFirmwareVersion = hilcam {}", env!("CARGO_PKG_VERSION"));
    assert!(ok && out.contains(&firmware) && out.contains("WidthMax = 320"), "{out}");
    // TLParamsLocked freezes Width (Aravis honours pIsLocked; the device refuses too).
    let (_, out) = run("arv-tool-0.8", control(ip, &["TLParamsLocked=1", "Width=100"])).await;
    assert_eq!(rig.device.settings().borrow().width, 320, "Width written while locked\n{out}");
    let (ok, out) = run("arv-tool-0.8", control(ip, &["TLParamsLocked=0", "Width=100", "TLParamsLocked"])).await;
    assert!(ok && out.contains("TLParamsLocked = 0") && out.contains("Width = 100"), "{out}");

    // Through the Python bindings: the offsets move WidthMax, a UTF-8 DeviceUserID, the
    // Timestamp chunk off and FrameID on; then 3 frames with Aravis' chunk parser.
    let sets = [
        "Width=200",
        "OffsetX=100",
        "Height=100",
        "OffsetY=40",
        "DeviceUserID=Kamera äöü",
        "ChunkModeActive=true",
        "ChunkSelector=Timestamp",
        "ChunkEnable=false",
        "--sfnc",
    ];
    let v = python_client(ip, 3, &sets).await;
    let s = &v["sfnc"];
    assert_eq!((s["WidthMax"].as_u64(), s["HeightMax"].as_u64()), (Some(220), Some(200)), "{v}");
    assert_eq!(s["DeviceUserID"], "Kamera äöü", "{v}");
    assert_eq!(s["ExposureMode"], "Timed");
    assert_eq!(s["ChunkModeActive"], true);
    let enabled = &s["ChunkEnable"];
    assert_eq!(
        (&enabled["Timestamp"], &enabled["ExposureTime"], &enabled["FrameID"], &enabled["HilcamMetadata"]),
        (&false.into(), &true.into(), &true.into(), &true.into()),
        "{v}"
    );
    let payload = 200 * 100 * 2 + hilcam_core::sink::gige::chunk::CHUNK_OVERHEAD as u64 - 16;
    assert_eq!(v["features"]["PayloadSize"].as_u64(), Some(payload), "the Timestamp chunk is not counted");
    for b in v["buffers"].as_array().unwrap() {
        assert_eq!(b["status"], "success", "{v}");
        let c = &b["chunks"];
        assert_eq!(c["ChunkTimestamp"], serde_json::Value::Null, "disabled: {v}");
        assert_eq!(c["ChunkFrameID"], b["frame_id"], "ChunkFrameID is the block id: {v}");
        assert_eq!(c["ChunkExposureTime"].as_f64(), Some(1000.0), "the frame integrated 1 ms: {v}");
        assert!(b["meta"]["pose_seq"].as_u64().is_some(), "hilcam's metadata chunk beside them");
    }
    // Back on: the timestamp chunk is the leader's timestamp.
    let v = python_client(ip, 2, &["ChunkSelector=Timestamp", "ChunkEnable=true", "--sfnc"]).await;
    for b in v["buffers"].as_array().unwrap() {
        assert_eq!(b["chunks"]["ChunkTimestamp"], b["timestamp"], "{v}");
    }
}

fn genapi_python() -> PathBuf {
    let py = std::env::var_os("HILCAM_PYTHON")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache/hilcam/venv/bin/python")))
        .expect("no HOME and no HILCAM_PYTHON");
    let ok = std::process::Command::new(&py).args(["-c", "import genicam.genapi"]).status().is_ok_and(|s| s.success());
    assert!(ok, "{} cannot import genicam.genapi: run scripts/setup-python.sh (scripts/test.sh does)", py.display());
    py
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_reference_genapi_loads_the_xml_and_drives_the_camera_with_it() {
    let ip = Ipv4Addr::new(127, 0, 0, 66);
    let rig = Rig::start(ip, 320, 240).await;
    let dir = tempfile::tempdir().unwrap();
    let xml = dir.path().join("hilcam.xml");
    std::fs::write(&xml, rig.device.xml()).unwrap();
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/gige_client/genapi_check.py");
    let args = [script, xml.to_str().unwrap(), &ip.to_string(), "Width=256", "OffsetX=64", "DeviceUserID=Kamera äöü"];
    let out = tokio::task::spawn_blocking({
        let py = genapi_python();
        let args = args.map(String::from);
        move || std::process::Command::new(py).args(args).output().unwrap()
    })
    .await
    .unwrap();
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "the reference GenApi refused the XML or the camera:\n{text}");
    let v: serde_json::Value = serde_json::from_str(text.lines().rev().find(|l| l.starts_with('{')).unwrap()).unwrap();
    let f = |name: &str| &v[name]["value"];
    assert_eq!((f("Width"), f("OffsetX"), f("WidthMax")), (&256.into(), &64.into(), &256.into()), "{v}");
    assert_eq!(v["Width"]["max"], 256, "the Width range follows OffsetX: {v}");
    assert_eq!(v["OffsetX"]["max"], 64, "and OffsetX's follows Width: {v}");
    assert_eq!(f("DeviceUserID"), "Kamera äöü");
    assert_eq!(f("ExposureMode"), "Timed");
    assert_eq!(f("ChunkSelector"), "Timestamp");
    assert_eq!(f("TLParamsLocked"), 0);
    assert_eq!(v["GevSCPD"]["max"], u64::from(hilcam_core::sink::gige::registers::SCPD_MAX_TICKS));
    for (name, entry) in v.as_object().unwrap() {
        let value = entry["value"].as_str().unwrap_or("");
        assert!(!value.starts_with("error"), "{name}: {value}");
    }
}

#[test]
fn aravis_discovers_the_camera_by_its_limited_broadcast() {
    if !netns::enter("gige_sfnc::aravis_discovers_the_camera_by_its_limited_broadcast") {
        return;
    }
    let rt = tokio::runtime::Builder::new_multi_thread().worker_threads(2).enable_all().build().unwrap();
    rt.block_on(async {
        // Not the address Aravis sends from (127.0.0.1): only a broadcast finds it.
        let ip = Ipv4Addr::new(127, 0, 0, 5);
        let rig = Rig::start(ip, 64, 48).await;
        let (ok, out) = run("arv-tool-0.8", vec![]).await;
        assert!(ok && out.contains("(127.0.0.5)"), "arv-tool-0.8 did not list the camera:\n{out}");
        println!("{out}");
        assert!(rig.counter("hilcam_gige_broadcast_discoveries_total", &[]) >= 1, "heard on 255.255.255.255");
    });
}
