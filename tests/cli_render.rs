//! `hilcam render`: its timing options (`--warm-up` frames and `--repeat` change the time
//! reported, never the image) and a fractional `--spp`.

use std::process::Command;

fn render(out: &std::path::Path, extra: &[&str]) -> String {
    render_spp("2", out, extra)
}

fn render_spp(spp: &str, out: &std::path::Path, extra: &[&str]) -> String {
    let o = Command::new(env!("CARGO_BIN_EXE_hilcam"))
        .args(["render", "scenes/satellite_lambert.toml", "--width", "96", "--spp", spp, "--out"])
        .arg(out)
        .args(extra)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8(o.stdout).unwrap()
}

#[test]
fn warm_up_and_repeat_keep_the_image() {
    let dir = tempfile::tempdir().unwrap();
    let (cold, warm) = (dir.path().join("cold.pfm"), dir.path().join("warm.pfm"));
    render(&cold, &[]);
    let said = render(&warm, &["--warm-up", "2", "--repeat", "3"]);
    assert!(said.contains("3 renders: median"), "{said}");
    let (a, b) = (std::fs::read(&cold).unwrap(), std::fs::read(&warm).unwrap());
    assert!(a.len() > 96 * 96 * 4);
    assert!(a == b, "the warm frame's image differs from the cold one's");
}

#[test]
fn warm_up_keeps_the_sensor_image() {
    let dir = tempfile::tempdir().unwrap();
    let (cold, warm) = (dir.path().join("cold.pfm"), dir.path().join("warm.pfm"));
    render(&cold, &["--sensor"]);
    render(&warm, &["--sensor", "--warm-up", "2"]);
    let (a, b) = (std::fs::read(&cold).unwrap(), std::fs::read(&warm).unwrap());
    assert!(a.len() > 96 * 96 * 4);
    assert!(a == b, "warm-up frames changed the sensor's output (its auto-exposure must not see them)");
}

#[test]
fn a_fractional_budget_renders_and_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("f.pfm");
    let said = render_spp("1.25", &out, &[]);
    assert!(said.contains("spp 1.25 (adaptive, average)"), "{said}");
    let o = Command::new(env!("CARGO_BIN_EXE_hilcam"))
        .args(["render", "scenes/satellite_lambert.toml", "--width", "96", "--spp", "0.5", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("--spp") && err.contains("at least 1"), "{err}");
}
