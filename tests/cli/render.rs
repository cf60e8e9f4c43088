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

#[test]
fn an_roi_is_the_full_frames_pixels_there_and_one_outside_the_sensor_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let (full, part) = (dir.path().join("full.pfm"), dir.path().join("roi.pfm"));
    render(&full, &["--sensor", "--no-adaptive"]);
    let said = render(&part, &["--sensor", "--no-adaptive", "--roi", "20,30,40,24", "--repeat", "2"]);
    assert!(said.contains("roi.pfm: 40x24 spp 2"), "{said}");
    let (full, part) =
        (hilcam_core::render::film::read_pfm(&full).unwrap(), hilcam_core::render::film::read_pfm(&part).unwrap());
    assert_eq!((part.width, part.height), (40, 24));
    for row in 0..24 {
        let want = &full.data[(30 + row) * 96 + 20..(30 + row) * 96 + 60];
        assert_eq!(&part.data[row * 40..(row + 1) * 40], want, "row {row} of the ROI");
    }
    assert!(part.data.iter().any(|v| *v > 0.0), "the ROI sees the target");
    let o = run("2", &dir.path().join("x.pfm"), &["--sensor", "--roi", "90,0,10,10"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--roi: window 10x10 at (90, 0) is not inside the 96x96 sensor"), "{err}");
}
