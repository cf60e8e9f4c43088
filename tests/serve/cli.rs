//! The serve configuration files and `hilcam demo` from the command line.

use hilcam_core::serve::config::ServeConfig;
use std::process::Command;

#[test]
fn shipped_serve_configs_load() {
    let mut kinds = std::collections::BTreeSet::new();
    for entry in std::fs::read_dir("config").unwrap() {
        let f = entry.unwrap().path();
        if !f.file_name().unwrap().to_string_lossy().starts_with("serve-") {
            continue;
        }
        let c = ServeConfig::load(&f).unwrap_or_else(|e| panic!("{e}"));
        kinds.insert(c.input.kind());
        assert!(c.scene.ends_with("scenes/satellite.toml") && c.scene.exists(), "{}", c.scene.display());
    }
    // docs/serve-config.md promises a shipped example for each input kind.
    assert_eq!(kinds.into_iter().collect::<Vec<_>>(), ["serial", "slcan", "socketcan", "trajectory"]);
}

#[test]
fn config_errors_name_the_file_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let write = |text: &str| {
        let p = dir.path().join("serve.toml");
        std::fs::write(&p, text).unwrap();
        ServeConfig::load(&p).err().map(|e| e.to_string()).unwrap_or_default()
    };
    let e = write("scene = \"s.toml\"\n[trigger]\nmode = \"rate\"\n");
    assert!(e.contains("serve.toml") && e.contains("trigger.rate_hz"), "{e}");
    let e = write("scene = \"s.toml\"\n[input]\nkind = \"serial\"\n");
    assert!(e.contains("serve.toml") && e.contains("missing field `device`"), "{e}");
    let e = write("scene = \"s.toml\"\n[stream]\nlisten = \"nowhere\"\n");
    assert!(e.contains("line 3"), "{e}");
    let e = write("scene = \"s.toml\"\n[input]\nkind = \"slcan\"\ndevice = \"/dev/x\"\nbitrate = 1000\n");
    assert!(e.contains("input.bitrate") && e.contains("1000 bit/s is not an slcan rate"), "{e}");
    let e = write("scene = \"s.toml\"\n[record]\nformat = \"png\"\n");
    assert!(e.contains("serve.toml") && e.contains("record: needs `dir`"), "{e}");
    let e = write("scene = \"s.toml\"\n[record]\nsesion = \"x.jsonl\"\n");
    assert!(e.contains("line 3") && e.contains("sesion"), "{e}");
    let p = dir.path().join("serve.toml");
    std::fs::write(&p, "scene = \"s.toml\"\n[record]\nsession = \"runs/a.session.jsonl\"\n").unwrap();
    let r = ServeConfig::load(&p).unwrap().record.unwrap();
    assert_eq!((r.dir, r.session), (None, Some(dir.path().join("runs/a.session.jsonl"))));
}

#[test]
fn demo_runs_the_whole_loop_and_says_where_the_frames_are() {
    let out = tempfile::tempdir().unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_hilcam"))
        .args(["demo", "--frames", "3", "--out"])
        .arg(out.path())
        .env("HILCAM_LOG", "warn")
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout.contains("client: 3 frames") && stdout.contains("CRC errors 0"), "{stdout}");
    assert!(stdout.contains(&out.path().display().to_string()), "{stdout}");
    for i in 0..3 {
        assert!(out.path().join(format!("frame_{i:010}.png")).is_file());
    }
    assert!(out.path().join("preview.png").is_file() && out.path().join("summary.txt").is_file());
}
