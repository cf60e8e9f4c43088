//! Every entry point that takes a pose or a scene value, driven over the whole f64 space —
//! NaN, ±inf, subnormals, ±0, 1e±300, f64::MAX, zero vectors — as a bench could send
//! them. Each input either comes back as a named rejection or renders a frame whose
//! pixels are finite and non-negative; nothing panics.

use glam::{DQuat, DVec3};
use hilcam_core::frame::{DecodeError, HEADER_LEN, decode_frame};
use hilcam_core::pipeline::FramePipeline;
use hilcam_core::pose::can::{self, CanAssembler, CanEvent, CanIds};
use hilcam_core::pose::trajectory::Trajectory;
use hilcam_core::pose::validate::{PoseLimits, check_pose};
use hilcam_core::pose::{Message, Pose, serial};
use hilcam_core::scene::Scene;
use proptest::prelude::*;
use std::path::Path;
use std::sync::{Arc, OnceLock};

/// The values a hostile or broken sender produces, and ordinary ones around them.
fn any_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        3 => prop::sample::select(vec![
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            0.0,
            -0.0,
            5e-324,
            -5e-324,
            f64::MIN_POSITIVE,
            1e-300,
            1e-150,
            1e150,
            1.3e154,
            1e300,
            -1e300,
            f64::MAX,
            f64::MIN,
            1.0,
            -1.0,
        ]),
        2 => -20.0f64..20.0,
        1 => any::<f64>(),
    ]
}

fn any_vec() -> impl Strategy<Value = DVec3> {
    prop_oneof![
        1 => Just(DVec3::ZERO),
        6 => (any_f64(), any_f64(), any_f64()).prop_map(|(x, y, z)| DVec3::new(x, y, z)),
    ]
}

fn any_quat() -> impl Strategy<Value = DQuat> {
    prop_oneof![
        1 => Just(DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0)),
        1 => (-3.0f64..3.0, -3.0f64..3.0, -3.0f64..3.0).prop_map(|(a, b, c)| DQuat::from_euler(glam::EulerRot::XYZ, a, b, c)),
        4 => (any_f64(), any_f64(), any_f64(), any_f64()).prop_map(|(w, x, y, z)| DQuat::from_xyzw(x, y, z, w)),
    ]
}

/// A pose in front of the camera, nudged, or fully hostile.
fn any_pose() -> impl Strategy<Value = Pose> {
    let position = prop_oneof![
        1 => (-1.0f64..1.0, -1.0f64..1.0, 2.0f64..50.0).prop_map(|(x, y, z)| DVec3::new(x, y, z)),
        2 => any_vec(),
    ];
    let sun = prop_oneof![
        1 => (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0).prop_map(|(x, y, z)| DVec3::new(x, y, z).normalize_or(DVec3::Z)),
        2 => any_vec(),
    ];
    let rates = prop_oneof![2 => Just(None), 1 => any_vec().prop_map(Some)];
    (any::<u32>(), any::<u64>(), position, any_quat(), sun, rates.clone(), rates).prop_map(
        |(seq, t_ns, position, attitude, sun_dir, velocity, angular_rate)| Pose {
            seq,
            t_ns,
            position,
            attitude,
            sun_dir,
            velocity,
            angular_rate,
            camera_to_inertial: None,
            planet_centre: None,
        },
    )
}

/// The shipped Lambert plate, at 8×8 pixels, loaded once.
fn plate() -> &'static Arc<Scene> {
    static SCENE: OnceLock<Arc<Scene>> = OnceLock::new();
    SCENE.get_or_init(|| {
        let mut s = hilcam_core::scene::load(Path::new("scenes/plate.toml")).unwrap();
        s.camera = s.camera.scaled(Some(8), None);
        Arc::new(s)
    })
}

/// Render `pose` as serve and replay do: the radiance has finite, non-negative pixels,
/// and the sensor turns it into a frame without error.
fn render_checked(pose: &Pose) -> Result<(), TestCaseError> {
    let scene = plate();
    let mut pipeline = FramePipeline::new(scene.clone(), scene.camera.clone()).unwrap();
    let settings = hilcam_core::render::integrator::RenderSettings {
        spp: hilcam_core::render::integrator::Spp::whole(2),
        depth: 2,
        ..scene.render
    };
    let (img, _) = pipeline.radiance(pose, &settings, 0);
    prop_assert!(img.data.iter().all(|x| x.is_finite() && *x >= 0.0), "pose {pose:?}: {:?}", img.data);
    let f = pipeline.frame(pose, &settings, 0).map_err(|e| TestCaseError::fail(format!("sensor: {e}")))?;
    prop_assert_eq!(f.pixels.len(), 64);
    Ok(())
}

/// The gate's answer for `p`: a named rejection (its text is non-empty), or a pose whose
/// attitude and sun are unit vectors, which then renders finite pixels.
fn gate_then_render(p: &Pose) -> Result<(), TestCaseError> {
    match check_pose(p, &PoseLimits::default()) {
        Err(r) => {
            prop_assert!(!r.to_string().is_empty() && !r.as_str().is_empty());
            Ok(())
        }
        Ok(ok) => {
            prop_assert!((ok.attitude.length() - 1.0).abs() < 1e-12 && (ok.sun_dir.length() - 1.0).abs() < 1e-12);
            prop_assert!(ok.position.is_finite());
            render_checked(&ok)
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1000, failure_persistence: None, ..ProptestConfig::default() })]

    /// Serial link: any pose a sender can encode is decoded bit for bit, then gated.
    #[test]
    fn serial_poses_are_rejected_by_name_or_render_finite(p in any_pose()) {
        let bytes = serial::encode_frame(&Message::Pose(p));
        let (msg, used) = serial::decode_frame(&bytes).expect("a frame hilcam encoded decodes");
        prop_assert_eq!(used, bytes.len());
        let Message::Pose(q) = msg else { return Err(TestCaseError::fail("not a pose")) };
        gate_then_render(&q)?;
    }

    /// CAN link (classic groups and FD): encoding saturates what f32/Q23/Q15 cannot hold;
    /// whatever arrives is gated.
    #[test]
    fn can_poses_are_rejected_by_name_or_render_finite(p in any_pose(), fd in any::<bool>()) {
        let ids = CanIds::default();
        let mut a = CanAssembler::new(ids);
        let mut got = None;
        for f in can::encode_message(ids, &Message::Pose(p), fd) {
            if let Some(CanEvent::Message(Message::Pose(q))) = a.push(&f) {
                got = Some(q);
            }
        }
        let q = got.expect("a group hilcam encoded assembles");
        gate_then_render(&q)?;
    }

    /// Offline replay and serve's trajectory input: a row is refused with file:line and
    /// reason, or renders. (NaN/inf are refused by the CSV parser, also by line.)
    #[test]
    fn trajectory_rows_are_refused_with_their_line_or_render_finite(p in any_pose()) {
        let dir = tempfile::tempdir().unwrap();
        let csv = dir.path().join("t.csv");
        let (q, s) = (p.attitude, p.sun_dir);
        let row = format!(
            "0,{:?},{:?},{:?},{:?},{:?},{:?},{:?},{:?},{:?},{:?}",
            p.position.x, p.position.y, p.position.z, q.w, q.x, q.y, q.z, s.x, s.y, s.z
        );
        std::fs::write(&csv, format!("time_s,px,py,pz,qw,qx,qy,qz,sx,sy,sz\n{row}\n")).unwrap();
        match Trajectory::load_gated(&csv, &PoseLimits::default()) {
            Err(e) => {
                let e = e.to_string();
                prop_assert!(e.starts_with(&format!("{}:2:", csv.display())), "{e}");
            }
            Ok(samples) => render_checked(&samples[0].to_pose(0))?,
        }
    }

    /// The renderer itself, for a library caller who skips the gate: no panic, no NaN.
    #[test]
    fn the_renderer_never_panics_or_writes_nan_even_for_ungated_poses(p in any_pose()) {
        render_checked(&p)?;
    }

    /// `hilcam recv`'s decoder: any header that passes its CRC either names what is wrong
    /// or describes a payload within the camera limits; nothing allocates from it first.
    #[test]
    fn frame_headers_with_any_fields_are_rejected_by_name_or_bounded(
        width in prop_oneof![Just(0u32), Just(u32::MAX), Just(1u32 << 31), 1u32..20_000],
        height in prop_oneof![Just(0u32), Just(u32::MAX), Just(1u32 << 31), 1u32..20_000],
        format in 0u8..5,
        bits in any::<u8>(),
        payload_len in prop_oneof![Just(u64::MAX), Just(0u64), any::<u64>()],
    ) {
        let mut h = [0u8; HEADER_LEN];
        h[0..4].copy_from_slice(b"HLCF");
        h[4..6].copy_from_slice(&1u16.to_le_bytes());
        h[6..8].copy_from_slice(&(HEADER_LEN as u16).to_le_bytes());
        h[48..52].copy_from_slice(&width.to_le_bytes());
        h[52..56].copy_from_slice(&height.to_le_bytes());
        h[56] = format;
        h[57] = bits;
        h[58..60].copy_from_slice(&1u16.to_le_bytes());
        h[72..80].copy_from_slice(&payload_len.to_le_bytes());
        let crc = hilcam_core::frame::CRC32.checksum(&h[..84]);
        h[84..88].copy_from_slice(&crc.to_le_bytes());
        match decode_frame(&h) {
            Err(DecodeError::Malformed(m)) => prop_assert!(!m.to_string().is_empty()),
            Err(DecodeError::Incomplete { .. }) => {
                prop_assert!(width <= 16_384 && height <= 16_384, "{width}x{height} accepted as a header");
                prop_assert!(payload_len <= 16_384 * 16_384 * 4);
            }
            Ok((f, _)) => prop_assert_eq!(f.pixels.len(), 0),
        }
    }

}

/// `sane` most of the time, any value a hostile file could hold otherwise (so that a case
/// usually has one or two hostile fields and the ones that pass still render).
fn mostly(sane: f64) -> impl Strategy<Value = f64> {
    prop_oneof![7 => Just(sane), 1 => any_f64()]
}

/// A TOML float literal for any f64 (TOML spells the special values `nan`, `inf`, `-inf`).
fn toml_f64(v: f64) -> String {
    if v.is_nan() {
        "nan".into()
    } else if v.is_infinite() {
        if v > 0.0 { "inf".into() } else { "-inf".into() }
    } else {
        format!("{v:?}")
    }
}

fn toml_vec(v: &[f64]) -> String {
    format!("[{}]", v.iter().map(|x| toml_f64(*x)).collect::<Vec<_>>().join(", "))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, failure_persistence: None, ..ProptestConfig::default() })]

    /// Scene files: every numeric value a scene takes, hostile or not, is refused with the
    /// file, line and field, or the scene renders finite, non-negative pixels.
    #[test]
    fn scene_values_are_refused_with_file_line_and_field_or_render_finite(
        background in mostly(0.0),
        irradiance in mostly(593.1),
        rho in mostly(0.5),
        translate in (mostly(0.0), mostly(0.0), mostly(0.0)),
        rotate in (mostly(0.0), mostly(30.0), mostly(0.0)),
        scale in mostly(1.0),
        position in (mostly(0.1), mostly(0.0), mostly(10.0)),
        attitude in (mostly(1.0), mostly(0.0), mostly(0.0), mostly(0.0)),
        sun in (mostly(0.5), mostly(0.0), mostly(-0.866)),
    ) {
        let p = Pose {
            position: DVec3::new(position.0, position.1, position.2),
            attitude: DQuat::from_xyzw(attitude.1, attitude.2, attitude.3, attitude.0),
            sun_dir: DVec3::new(sun.0, sun.1, sun.2),
            ..Pose::ahead(10.0)
        };
        let dir = tempfile::tempdir().unwrap();
        let mesh = std::fs::canonicalize("scenes/meshes/plate.obj").unwrap();
        let q = p.attitude;
        let text = format!(
            "[[mesh]]\nobj = \"{}\"\ntranslate = {}\nrotate_deg = {}\nscale = {}\n\
             [materials.white_paint]\nmodel = \"lambert\"\nrho = {}\n\
             [sun]\nirradiance = {}\n[background]\nradiance = {}\n\
             [camera]\nwidth = 8\nheight = 8\npitch_um = 10.0\nfocal_mm = 50.0\n\
             [pose]\nposition = {}\nattitude = {}\nsun = {}\n[render]\nspp = 2\ndepth = 2\n",
            mesh.display(),
            toml_vec(&[translate.0, translate.1, translate.2]),
            toml_vec(&[rotate.0, rotate.1, rotate.2]),
            toml_f64(scale),
            toml_f64(rho),
            toml_f64(irradiance),
            toml_f64(background),
            toml_vec(&p.position.to_array()),
            toml_vec(&[q.w, q.x, q.y, q.z]),
            toml_vec(&p.sun_dir.to_array()),
        );
        let path = dir.path().join("s.toml");
        std::fs::write(&path, &text).unwrap();
        match hilcam_core::scene::load(&path) {
            Err(e) => {
                let e = e.to_string();
                prop_assert!(e.starts_with(&path.display().to_string()), "unnamed error: {e}");
            }
            Ok(scene) => {
                let scene = Arc::new(scene);
                let (img, _) = FramePipeline::new(scene.clone(), scene.camera.clone())
                    .unwrap()
                    .radiance(&scene.pose, &scene.render, 0);
                prop_assert!(img.data.iter().all(|v| v.is_finite() && *v >= 0.0), "{text}");
            }
        }
    }
}
