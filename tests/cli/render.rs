//! `hilcam render`: its timing options (`--warm-up` frames and `--repeat` change the time
//! reported, never the image) and a fractional `--spp`.

use std::process::Command;

fn render(out: &std::path::Path, extra: &[&str]) -> String {
    render_spp("2", out, extra)
}

fn render_spp(spp: &str, out: &std::path::Path, extra: &[&str]) -> String {
    let o = run(spp, out, extra);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8(o.stdout).unwrap()
}

fn run(spp: &str, out: &std::path::Path, extra: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_hilcam"))
        .args(["render", "scenes/satellite_lambert.toml", "--width", "96", "--spp", spp, "--out"])
        .arg(out)
        .args(extra)
        .output()
        .unwrap()
}

/// The images at `a` and `b` have the same bytes (and are more than a header).
fn assert_same_image(a: &std::path::Path, b: &std::path::Path, why: &str) {
    let (a, b) = (std::fs::read(a).unwrap(), std::fs::read(b).unwrap());
    assert!(a.len() > 96 * 96 * 4);
    assert!(a == b, "{why}");
}

#[test]
fn warm_up_and_repeat_keep_the_image() {
    let dir = tempfile::tempdir().unwrap();
    let (cold, warm) = (dir.path().join("cold.pfm"), dir.path().join("warm.pfm"));
    render(&cold, &[]);
    let said = render(&warm, &["--warm-up", "2", "--repeat", "3"]);
    assert!(said.contains("3 renders: median"), "{said}");
    assert_same_image(&cold, &warm, "the warm frame's image differs from the cold one's");
}

#[test]
fn warm_up_keeps_the_sensor_image() {
    let dir = tempfile::tempdir().unwrap();
    let (cold, warm) = (dir.path().join("cold.pfm"), dir.path().join("warm.pfm"));
    render(&cold, &["--sensor"]);
    render(&warm, &["--sensor", "--warm-up", "2"]);
    assert_same_image(&cold, &warm, "warm-up frames changed the sensor's output (its auto-exposure must not see them)");
}

#[test]
fn a_fractional_budget_renders_and_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("f.pfm");
    let said = render_spp("1.25", &out, &[]);
    assert!(said.contains("spp 1.25 (adaptive, average)"), "{said}");
    let said = render_spp("1.25", &out, &["--no-adaptive"]);
    assert!(said.contains("spp 1.25 (average)"), "{said}");
    let o = run("0.5", &out, &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("--spp") && err.contains("at least 1"), "{err}");
}
