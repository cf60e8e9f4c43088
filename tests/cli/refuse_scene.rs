//! Hostile scene files, camera files, OBJ files, flags and frame headers, as a user (or an
//! adversary) would give them to the binary: each is refused with a non-zero exit, no
//! panic, and an error naming the file and line and field (or the flag) and the limit or
//! the reason.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_hilcam");

/// A one-triangle OBJ with default material, a camera file, and a scene that uses them.
struct Fixture {
    dir: tempfile::TempDir,
}

const OBJ: &str = "v -0.5 -0.5 0\nv 0.5 -0.5 0\nv 0 0.5 0\nf 1 2 3\n";
const CAMERA: &str = "[camera]\nwidth = 16\nheight = 16\npitch_um = 10.0\nfocal_mm = 20.0\n";

/// Line 1 camera file, 3-5 mesh, 7-9 material, 11-12 sun, 14-15 background, 17-20 pose,
/// 22-24 render; `extra` from line 25 on.
fn scene_text(extra: &str) -> String {
    format!(
        "camera_file = \"cam.toml\"\n\n\
         [[mesh]]\nobj = \"t.obj\"\nscale = 1.0\n\n\
         [materials.default]\nmodel = \"lambert\"\nrho = 0.5\n\n\
         [sun]\nirradiance = 593.1\n\n\
         [background]\nradiance = 0.0\n\n\
         [pose]\nposition = [0.0, 0.0, 5.0]\nattitude = [1.0, 0.0, 0.0, 0.0]\nsun = [0.0, 0.0, -1.0]\n\n\
         [render]\nspp = 1\ndepth = 1\n{extra}"
    )
}

impl Fixture {
    fn new() -> Fixture {
        let f = Fixture { dir: tempfile::tempdir().unwrap() };
        f.write("t.obj", OBJ);
        f.write("cam.toml", CAMERA);
        f.write("s.toml", &scene_text(""));
        f
    }

    fn write(&self, name: &str, text: &str) -> PathBuf {
        let p = self.dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    /// `hilcam render s.toml --out x.pfm` plus `args`.
    fn render(&self, args: &[&str]) -> Output {
        Command::new(BIN)
            .arg("render")
            .arg(self.path("s.toml"))
            .arg("--out")
            .arg(self.path("out.pfm"))
            .args(args)
            .env("HILCAM_LOG", "warn")
            .output()
            .unwrap()
    }

    /// Replace `from` by `to` in the scene text (which must contain it) and render.
    fn render_edited(&self, from: &str, to: &str) -> String {
        let text = scene_text("");
        assert!(text.contains(from), "fixture has no `{from}`");
        self.write("s.toml", &text.replacen(from, to, 1));
        refused(&self.render(&[]))
    }
}

/// Asserts a refusal (non-zero exit, no panic) and returns stderr.
fn refused(o: &Output) -> String {
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(!o.status.success(), "accepted; stdout: {}", String::from_utf8_lossy(&o.stdout));
    assert!(!err.contains("panicked"), "panicked: {err}");
    assert!(o.status.code().is_some(), "killed by a signal (abort?): {err}");
    err
}

fn has_all(e: &str, parts: &[&str]) {
    for p in parts {
        assert!(e.contains(p), "`{p}` missing from: {e}");
    }
}

#[test]
fn the_fixture_renders() {
    let f = Fixture::new();
    let o = f.render(&[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let img = hilcam_core::render::film::read_pfm(&f.path("out.pfm")).unwrap();
    assert_eq!((img.width, img.height), (16, 16));
    assert!(img.data.iter().any(|v| *v > 0.0), "the triangle is lit");
}

#[test]
fn width_flags_out_of_range_are_refused_naming_the_flag_and_limit() {
    let f = Fixture::new();
    has_all(&refused(&f.render(&["--width", "0"])), &["--width", "1..=16384", "got 0"]);
    has_all(&refused(&f.render(&["--width", "65536"])), &["--width", "1..=16384", "65536"]);
    has_all(&refused(&f.render(&["--height", "65536"])), &["--height", "1..=16384"]);
}

#[test]
fn camera_file_sizes_out_of_range_are_refused() {
    let f = Fixture::new();
    f.write("cam.toml", &CAMERA.replace("height = 16", "height = 65536"));
    has_all(&refused(&f.render(&[])), &["s.toml:1:", "camera_file", "cam.toml", "camera.height", "1..=16384"]);
    f.write("cam.toml", &CAMERA.replace("width = 16", "width = 0"));
    has_all(&refused(&f.render(&[])), &["cam.toml", "camera.width", "1..=16384", "got 0"]);
}

#[test]
fn inline_camera_size_out_of_range_is_refused() {
    let f = Fixture::new();
    let inline = "[camera]\nwidth = 65536\nheight = 16\npitch_um = 10.0\nfocal_mm = 20.0\n";
    // The camera_file line left blank, so that the line numbers stay.
    f.write("s.toml", &(scene_text("").replace("camera_file = \"cam.toml\"\n", "\n") + inline));
    has_all(&refused(&f.render(&[])), &["s.toml:25:", "camera.width", "1..=16384", "65536"]);
}

#[test]
fn serve_config_width_out_of_range_refuses_to_start() {
    let f = Fixture::new();
    let cfg = f.write("serve.toml", "scene = \"s.toml\"\nwidth = 1000000\n[input]\nkind = \"none\"\n");
    let o = Command::new(BIN).args(["serve", "--config"]).arg(&cfg).env("HILCAM_LOG", "warn").output().unwrap();
    has_all(&refused(&o), &["serve.toml", "width", "1..=16384", "1000000"]);
}

#[test]
fn a_wrap_edge_that_would_explode_the_mesh_is_refused() {
    let f = Fixture::new();
    f.write("s.toml", &scene_text("\n[[wrap]]\nmaterial = \"default\"\nlevel = \"medium\"\nedge_m = 1e-5\n"));
    has_all(&refused(&f.render(&[])), &["s.toml:29:", "wrap[0].edge_m", "triangles", "limit 10000000"]);
}

#[test]
fn non_finite_or_negative_background_is_refused() {
    let f = Fixture::new();
    for bad in ["nan", "inf", "-5.0"] {
        let e = f.render_edited("radiance = 0.0", &format!("radiance = {bad}"));
        has_all(&e, &["s.toml:15:", "background.radiance", "[0, 1000000]"]);
    }
}

#[test]
fn bad_obj_vertices_are_named_by_obj_file_and_line() {
    let f = Fixture::new();
    for bad in ["nan", "inf", "1e39"] {
        f.write("t.obj", &OBJ.replace("v 0.5 -0.5 0", &format!("v {bad} -0.5 0")));
        let e = refused(&f.render(&[]));
        has_all(&e, &["s.toml:4:", "mesh[0].obj", "t.obj:2:", "vertex x", bad]);
    }
}

#[test]
fn non_finite_transforms_are_refused() {
    let f = Fixture::new();
    let e = f.render_edited("scale = 1.0", "scale = 1.0\ntranslate = [nan, 0.0, 0.0]");
    has_all(&e, &["s.toml:6:", "mesh[0].translate", "finite"]);
    let e = f.render_edited("scale = 1.0", "scale = 1.0\nrotate_deg = [0.0, inf, 0.0]");
    has_all(&e, &["s.toml:6:", "mesh[0].rotate_deg", "[-360, 360]"]);
    let e = f.render_edited("scale = 1.0", "scale = inf");
    has_all(&e, &["s.toml:5:", "mesh[0].scale"]);
}

#[test]
fn sun_irradiance_beyond_the_range_is_refused() {
    let f = Fixture::new();
    let e = f.render_edited("irradiance = 593.1", "irradiance = 1e308");
    has_all(&e, &["s.toml:12:", "sun.irradiance", "1000000", "1e308"]);
}

#[test]
fn a_huge_sun_direction_is_normalised_and_renders_lit() {
    // Decided: a direction's length carries no meaning, so a finite huge one is scaled by
    // its largest component and normalised; the frame is the same as for the unit vector.
    let f = Fixture::new();
    f.write("s.toml", &scene_text("").replace("sun = [0.0, 0.0, -1.0]", "sun = [1e300, 0.0, -1e300]"));
    let o = f.render(&[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let huge = hilcam_core::render::film::read_pfm(&f.path("out.pfm")).unwrap();
    f.write("s.toml", &scene_text("").replace("sun = [0.0, 0.0, -1.0]", "sun = [1.0, 0.0, -1.0]"));
    assert!(f.render(&[]).status.success());
    let unit = hilcam_core::render::film::read_pfm(&f.path("out.pfm")).unwrap();
    assert!(huge.data.iter().any(|v| *v > 0.0), "not black");
    assert_eq!(huge.data, unit.data);
    // A zero sun is no direction.
    let e = f.render_edited("sun = [0.0, 0.0, -1.0]", "sun = [0.0, 0.0, 0.0]");
    has_all(&e, &["s.toml:20:", "pose.sun", "zero"]);
}

#[test]
fn scene_attitudes_off_the_unit_sphere_are_refused_by_the_pose_gate() {
    let f = Fixture::new();
    let e = f.render_edited("attitude = [1.0, 0.0, 0.0, 0.0]", "attitude = [2.0, 0.0, 0.0, 0.0]");
    has_all(&e, &["s.toml:19:", "pose.attitude", "quaternion norm outside tolerance", "norm 2", "tolerance 1e-3"]);
    let e = f.render_edited("attitude = [1.0, 0.0, 0.0, 0.0]", "attitude = [0.0, 0.0, 0.0, 0.0]");
    has_all(&e, &["s.toml:19:", "pose.attitude", "quaternion norm outside tolerance", "norm 0"]);
    let e = f.render_edited("position = [0.0, 0.0, 5.0]", "position = [0.0, 0.0, 1e200]");
    has_all(&e, &["s.toml:18:", "pose.position", "range above maximum"]);
}

#[test]
fn pose_flags_go_through_the_pose_gate() {
    let f = Fixture::new();
    has_all(&refused(&f.render(&["--pose", "nan,0,5"])), &["--pose", "pose.position", "non-finite"]);
    has_all(&refused(&f.render(&["--pose", "0,0,1e200"])), &["--pose", "pose.position", "range above maximum"]);
    has_all(&refused(&f.render(&["--pose", "0,0,5,2,0,0,0"])), &["--pose", "pose.attitude", "norm 2"]);
    has_all(&refused(&f.render(&["--pose", "0,0,5,0,0,0,0"])), &["--pose", "pose.attitude", "norm 0"]);
    has_all(&refused(&f.render(&["--pose", "0,0,5,1,0,0,0,0,0,0"])), &["--pose", "pose.sun", "zero"]);
    has_all(&refused(&f.render(&["--pose", "0,0,0.01"])), &["--pose", "range below minimum"]);
    assert!(f.render(&["--pose", "0,0,6,1,0,0,0,0,0,-3"]).status.success(), "a valid pose renders");
}

#[test]
fn recv_refuses_hostile_frame_headers_without_allocating() {
    use hilcam_core::frame::{DecodeError, Malformed, decode_header};
    let header = |w: u32, h: u32| {
        let mut b = [0u8; hilcam_core::frame::HEADER_LEN];
        b[0..4].copy_from_slice(b"HLCF");
        b[4..6].copy_from_slice(&1u16.to_le_bytes());
        b[6..8].copy_from_slice(&(hilcam_core::frame::HEADER_LEN as u16).to_le_bytes());
        b[48..52].copy_from_slice(&w.to_le_bytes());
        b[52..56].copy_from_slice(&h.to_le_bytes());
        b[56] = hilcam_core::frame::PixelFormat::Float32.code();
        b[57] = 32;
        b[58..60].copy_from_slice(&1u16.to_le_bytes());
        // payload_len: what the dimensions imply, wrapped as a naive u64 product would.
        let len = u64::from(w).wrapping_mul(u64::from(h)).wrapping_mul(4);
        b[72..80].copy_from_slice(&len.to_le_bytes());
        let crc = hilcam_core::frame::CRC32.checksum(&b[..84]);
        b[84..88].copy_from_slice(&crc.to_le_bytes());
        b
    };
    assert!(decode_header(&header(16, 16)).is_ok(), "the hand-built header is valid");
    for (w, h, field) in
        [(65536, 16, "width"), (16, 65536, "height"), (1 << 31, 1 << 31, "width"), (16, 16385, "height")]
    {
        match decode_header(&header(w, h)) {
            Err(DecodeError::Malformed(m @ Malformed::Dimension { .. })) => {
                has_all(&m.to_string(), &[field, "limit of 16384"]);
            }
            other => panic!("{w}x{h}: {other:?}"),
        }
    }

    // The client end to end: a server that sends the 2³¹ × 2³¹ header.
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    let bytes = header(1 << 31, 1 << 31);
    let server = std::thread::spawn(move || {
        use std::io::Write;
        let (mut s, _) = listener.accept().unwrap();
        s.write_all(&bytes).unwrap();
        std::thread::sleep(std::time::Duration::from_millis(200));
    });
    let out = tempfile::tempdir().unwrap();
    let o = Command::new(BIN)
        .args(["recv", "--count", "1", "--connect", &addr.to_string(), "--out"])
        .arg(out.path())
        .env("HILCAM_LOG", "warn")
        .output()
        .unwrap();
    server.join().unwrap();
    has_all(&refused(&o), &["width 2147483648 above the limit of 16384 pixels"]);
}

/// The path of a shipped scene, from the crate root.
fn shipped(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

#[test]
fn the_shipped_scenes_still_load() {
    for s in ["scenes/plate.toml", "scenes/satellite.toml", "scenes/corner.toml", "scenes/sphere.toml"] {
        hilcam_core::scene::file::parse(&shipped(s), &std::fs::read_to_string(shipped(s)).unwrap())
            .unwrap_or_else(|e| panic!("{e}"));
    }
}

mod bypassing_the_pose_gate {
    //! A library caller that renders poses the gate never saw: whatever the numbers, the
    //! renderer must not panic and every pixel must be finite and non-negative.

    use super::Fixture;
    use glam::{DQuat, DVec3};
    use hilcam_core::pipeline::FramePipeline;
    use hilcam_core::pose::Pose;
    use hilcam_core::render::camera::View;
    use proptest::prelude::*;
    use std::sync::{Arc, OnceLock};

    /// The whole f64 line's awkward corners, and ordinary values.
    fn wild() -> impl Strategy<Value = f64> {
        prop_oneof![
            Just(f64::NAN),
            Just(f64::INFINITY),
            Just(f64::NEG_INFINITY),
            Just(0.0),
            Just(-0.0),
            Just(f64::MIN_POSITIVE / 4.0),
            Just(-5e-324),
            Just(1e300),
            Just(-1e300),
            Just(1e-300),
            Just(f64::MAX),
            Just(1.3e154),
            -10.0..10.0f64,
            any::<f64>(),
        ]
    }

    fn pose() -> impl Strategy<Value = Pose> {
        (
            [wild(), wild(), wild()],
            prop_oneof![Just([1.0, 0.0, 0.0, 0.0]), [wild(), wild(), wild(), wild()]],
            [wild(), wild(), wild()],
        )
            .prop_map(|(p, q, s)| Pose {
                position: DVec3::from_array(p),
                attitude: DQuat::from_xyzw(q[1], q[2], q[3], q[0]),
                sun_dir: DVec3::from_array(s),
                ..Pose::ahead(5.0)
            })
    }

    /// The fixture scene with an 8 × 8 camera, loaded once.
    fn pipeline() -> &'static (Arc<hilcam_core::scene::Scene>, tempfile::TempDir) {
        static SCENE: OnceLock<(Arc<hilcam_core::scene::Scene>, tempfile::TempDir)> = OnceLock::new();
        SCENE.get_or_init(|| {
            let f = Fixture::new();
            f.write("cam.toml", &super::CAMERA.replace("16", "8"));
            let scene = hilcam_core::scene::load(&f.path("s.toml")).unwrap();
            (Arc::new(scene), f.dir)
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 300, failure_persistence: None, ..ProptestConfig::default() })]

        #[test]
        fn any_pose_renders_finite_non_negative_pixels(p in pose()) {
            let scene = &pipeline().0;
            let pl = FramePipeline::new(scene.clone(), scene.camera.clone()).unwrap();
            let (img, _) = pl.radiance(&p, &scene.render, 0);
            prop_assert_eq!(img.data.len(), 64);
            for v in &img.data {
                prop_assert!(v.is_finite() && *v >= 0.0, "pixel {} for {:?}", v, p);
            }
        }

        #[test]
        fn camera_rays_are_finite_or_missing(p in pose(), x in wild(), y in wild()) {
            let scene = &pipeline().0;
            let view = View::new(&scene.camera, &p, scene.frame_origin_body, scene.bounds);
            for (x, y) in [(x, y), (4.0, 4.0), (x, 4.0)] {
                if let Some(r) = view.primary_ray(x, y) {
                    prop_assert!(r.origin.is_finite() && r.dir.is_finite(), "{:?} at ({}, {}) for {:?}", r, x, y, p);
                    prop_assert!((r.dir.length() - 1.0).abs() < 1e-5, "{:?}", r);
                }
            }
            let _ = view.pixel_rect();
        }
    }

    #[test]
    fn a_good_pose_still_sees_the_target() {
        let scene = &pipeline().0;
        let pl = FramePipeline::new(scene.clone(), scene.camera.clone()).unwrap();
        let (img, _) = pl.radiance(&scene.pose, &scene.render, 0);
        assert!(img.data.iter().any(|v| *v > 0.0));
    }
}

/// `quality = "sensor"` measures the Monte Carlo noise against the camera's: refused for a
/// camera that has no detector, and for one whose detector has no temporal noise, from
/// the scene (naming its line), the render flag, and serve's `[render]`.
#[test]
fn sensor_quality_with_the_hybrid_method_is_refused() {
    // A hybrid frame has no per-pixel sample budget for "sensor" to spend.
    let f = Fixture::new();
    let noisy = "[sensor]\noutput = \"dn\"\n[sensor.detector]\nqe = 0.5\nread_noise_e = 3.0\n\
                 integration_time_s = 1e-3\n[sensor.adc]\nbits = 12\ngain_e_per_dn = 1.0\n[sensor.band]\n\
                 min_um = 0.45\nmax_um = 0.75\n[sensor.optics]\nf_number = 2.8\n";
    f.write("s.toml", &scene_text(&format!("method = \"hybrid\"\nquality = \"sensor\"\n{noisy}")));
    has_all(&refused(&f.render(&[])), &["s.toml:26:", "render.quality", "method = \"hybrid\"", "\"fixed\""]);
    // The flag cannot bring it back either.
    f.write("s.toml", &scene_text(&format!("method = \"hybrid\"\n{noisy}")));
    has_all(&refused(&f.render(&["--quality", "sensor", "--sensor"])), &["render.quality", "hybrid"]);
}

#[test]
fn sensor_quality_without_a_noisy_camera_is_refused() {
    let f = Fixture::new();
    f.write("s.toml", &scene_text("quality = \"sensor\"\n"));
    has_all(&refused(&f.render(&[])), &["s.toml:25:", "render.quality", "[sensor.detector]", "\"fixed\""]);
    f.write("s.toml", &scene_text(""));
    has_all(&refused(&f.render(&["--quality", "sensor", "--sensor"])), &["render.quality", "[sensor.detector]"]);
    let quiet = "[sensor]\noutput = \"dn\"\n[sensor.detector]\nqe = 0.5\nintegration_time_s = 1e-3\n\
                 [sensor.adc]\nbits = 12\ngain_e_per_dn = 1.0\n[sensor.band]\nmin_um = 0.45\nmax_um = 0.75\n\
                 [sensor.optics]\nf_number = 2.8\n";
    f.write("s.toml", &scene_text(&format!("quality = \"sensor\"\n{quiet}")));
    has_all(&refused(&f.render(&[])), &["s.toml:25:", "render.quality", "shot_noise = false", "no read_noise_e"]);
    // The same camera with read noise is accepted and reports its Monte Carlo noise.
    let noisy = quiet.replace("qe = 0.5\n", "qe = 0.5\nread_noise_e = 3.0\n");
    f.write("s.toml", &scene_text(&format!("quality = \"sensor\"\n{noisy}")));
    let o = Command::new(BIN)
        .arg("render")
        .arg(f.path("s.toml"))
        .args(["--sensor", "--out"])
        .arg(f.path("out.png"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("Monte Carlo noise: "),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    // serve's [render] quality over a scene without a detector: refused before serving.
    f.write("s.toml", &scene_text(""));
    let cfg = f.write("serve.toml", "scene = \"s.toml\"\n[input]\nkind = \"none\"\n[render]\nquality = \"sensor\"\n");
    let o = Command::new(BIN).args(["serve", "--config"]).arg(&cfg).env("HILCAM_LOG", "warn").output().unwrap();
    has_all(&refused(&o), &["render.quality", "s.toml", "[sensor.detector]"]);
}
