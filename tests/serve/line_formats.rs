//! The recorder's `frames.jsonl` line and the session file's `frame` line, pinned byte
//! for byte: readers outside hilcam parse these files, so any change to a name, the
//! field order or a number's spelling must show up here first.

use hilcam_core::frame::{FrameFlags, FrameMeta, PixelFormat};
use hilcam_core::render::integrator::{SamplerKind, Spp};
use hilcam_core::render::sampling::Sequence;
use hilcam_core::sensor::McNoiseStats;
use hilcam_core::session::{FrameLine, PoseFields, SessionLine, SettingsFields};
use hilcam_core::sink::recorder::{FrameRecord, ImageFormat, frame_file_name};
use std::path::Path;

/// A Mono16 payload of 3 × 2 pixels; its CRC-32 is 0x22e7b29a = 585609882
/// (Python: `zlib.crc32(struct.pack('<6H', 0, 1, 4095, 2048, 17, 65535))`).
fn payload() -> Vec<u8> {
    [0u16, 1, 4095, 2048, 17, 65535].iter().flat_map(|v| v.to_le_bytes()).collect()
}

#[test]
fn frames_jsonl_line_is_pinned_byte_for_byte() {
    let meta = FrameMeta {
        frame_seq: 4_294_967_301,
        pose_seq: 77,
        pose_t_ns: 1_234_567_890_123,
        pose_arrival_unix_ns: 1_700_000_000_123_456_789,
        emit_unix_ns: 1_700_000_000_987_654_321,
        width: 3,
        height: 2,
        format: PixelFormat::Mono16,
        bit_depth: 12,
        spp: Spp::from_milli(2_250),
        depth: 5,
        integration_s: 0.001,
        line_time_ns: 0,
        flags: FrameFlags(FrameFlags::LATE | FrameFlags::EXTRAPOLATED),
    };
    let rec = FrameRecord::new(&meta, &payload(), frame_file_name(meta.frame_seq, ImageFormat::Png));
    let line = serde_json::to_string(&rec).unwrap();
    let expected = concat!(
        r#"{"frame_seq":4294967301,"pose_seq":77,"pose_t_ns":1234567890123,"#,
        r#""pose_arrival_unix_ns":1700000000123456789,"emit_unix_ns":1700000000987654321,"#,
        r#""width":3,"height":2,"pixel_format":"Mono16","bit_depth":12,"spp":2.25,"depth":5,"#,
        r#""integration_s":0.001,"flags":3,"late":true,"extrapolated":true,"payload_len":12,"#,
        r#""payload_crc32":585609882,"file":"frame_4294967301.png"}"#,
    );
    assert_eq!(line, expected);
    let back: FrameRecord = serde_json::from_str(expected).unwrap();
    assert_eq!(back, rec, "the line reads back as the record it was written from");
}

#[test]
fn session_frame_line_is_pinned_byte_for_byte() {
    let line = SessionLine::Frame(FrameLine {
        index: 4_294_967_301,
        mono_ns: 250_000_000,
        source_seq: 77,
        source_mono_ns: 249_000_000,
        poses_received: 78,
        extrapolated_s: 0.0125,
        pose: PoseFields {
            seq: 77,
            t_ns: 1_234_567_890_123,
            position: [1.5, -2.25, 1000.125],
            attitude: [0.5, 0.5, -0.5, 0.5],
            sun_dir: [0.0, 0.6, 0.8],
            velocity: Some([0.1, -0.2, 0.3]),
            angular_rate: None,
            camera_to_inertial: None,
            planet_centre: None,
        },
        settings: SettingsFields {
            spp: Spp::from_milli(2_250),
            depth: 3,
            sampler: SamplerKind::Brdf,
            sequence: Sequence::Independent,
            roulette: false,
            adaptive: true,
            quality: hilcam_core::render::integrator::QualityGoal::FIXED,
            method: hilcam_core::render::integrator::Method::Path,
            seed: u64::MAX,
        },
        flags: FrameFlags::LATE | FrameFlags::EXTRAPOLATED | FrameFlags::DEGRADED,
        late: true,
        extrapolated: true,
        degraded: true,
        integration_s: Some(0.001),
        payload_crc32: 585_609_882,
        request: Default::default(),
        mc_noise: None,
    });
    let expected = concat!(
        r#"{"kind":"frame","index":4294967301,"mono_ns":250000000,"source_seq":77,"#,
        r#""source_mono_ns":249000000,"poses_received":78,"extrapolated_s":0.0125,"#,
        r#""pose":{"seq":77,"t_ns":1234567890123,"position":[1.5,-2.25,1000.125],"#,
        r#""attitude":[0.5,0.5,-0.5,0.5],"sun_dir":[0.0,0.6,0.8],"velocity":[0.1,-0.2,0.3]},"#,
        r#""settings":{"spp":2.25,"depth":3,"sampler":"brdf","sequence":"independent","roulette":false,"#,
        r#""adaptive":true,"seed":18446744073709551615},"flags":7,"late":true,"extrapolated":true,"#,
        r#""degraded":true,"integration_s":0.001,"payload_crc32":585609882}"#,
    );
    assert_eq!(line.encode(), expected);
    assert_eq!(SessionLine::decode(expected, Path::new("pin.session.jsonl"), 1).unwrap(), line);
}

/// The 3 × 2 Mono16 frame of [`payload`], frame 0, 1 spp, no flags.
fn small_meta() -> FrameMeta {
    FrameMeta {
        frame_seq: 0,
        pose_seq: 0,
        pose_t_ns: 0,
        pose_arrival_unix_ns: 0,
        emit_unix_ns: 0,
        width: 3,
        height: 2,
        format: PixelFormat::Mono16,
        bit_depth: 12,
        spp: Spp::ONE,
        depth: 1,
        integration_s: 0.0,
        line_time_ns: 0,
        flags: FrameFlags::default(),
    }
}

/// A `frames.jsonl` reader skips fields it does not know (a newer hilcam's log still
/// reads) but refuses an unknown pixel format, naming the file and line.
#[test]
fn frames_jsonl_reader_ignores_new_fields_and_names_the_line_of_an_unknown_pixel_format() {
    let meta = small_meta();
    let line = |seq: u64| {
        let m = FrameMeta { frame_seq: seq, ..meta };
        serde_json::to_string(&FrameRecord::new(&m, &payload(), frame_file_name(seq, ImageFormat::Png))).unwrap()
    };
    let newer = line(0).replacen('{', r#"{"sensor_temp_c":21.5,"#, 1);
    let back: FrameRecord = serde_json::from_str(&newer).unwrap();
    assert_eq!((back.meta, back.payload_crc32), (meta, 585_609_882), "an unknown field is skipped");

    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("frames.jsonl");
    let bad = line(1).replace(r#""pixel_format":"Mono16""#, r#""pixel_format":"Mono12""#);
    std::fs::write(&log, format!("{newer}\n{bad}\n")).unwrap();
    let e = hilcam_core::replay::merge(dir.path()).unwrap_err().to_string();
    let expected_start = format!("{}:2: not a frame record: unknown pixel_format \"Mono12\"", log.display());
    assert!(e.starts_with(&expected_start), "{e}");
    assert!(e.contains("expected Mono8, Mono16 or Float32"), "{e}");
}

/// A DN frame's `mc_noise` object (issue 27), pinned in both files: the same field names
/// and number spelling in `frames.jsonl` and in the session's `frame` line.
#[test]
fn mc_noise_object_is_pinned_in_both_lines() {
    let mc = McNoiseStats {
        k: 0.5,
        lit_pixels: 156_653,
        above_bound: 1_567,
        above_fraction: 1_567.0 / 156_653.0,
        above_shot: 12,
        mean_ratio: 0.25,
        rms_ratio: 0.375,
        mc_variance_e2_mean: 812.5,
    };
    let object = concat!(
        r#""mc_noise":{"k":0.5,"lit_pixels":156653,"above_bound":1567,"#,
        r#""above_fraction":0.01000300026172496,"above_shot":12,"mean_ratio":0.25,"rms_ratio":0.375,"#,
        r#""mc_variance_e2_mean":812.5}"#,
    );
    let meta = FrameMeta { frame_seq: 7, pose_seq: 7, ..small_meta() };
    let rec =
        FrameRecord { mc_noise: Some(mc), ..FrameRecord::new(&meta, &payload(), frame_file_name(7, ImageFormat::Png)) };
    let line = serde_json::to_string(&rec).unwrap();
    assert!(line.ends_with(&format!(r#""file":"frame_0000000007.png",{object}}}"#)), "{line}");
    assert_eq!(serde_json::from_str::<FrameRecord>(&line).unwrap(), rec);

    let frame = FrameLine {
        index: 7,
        mono_ns: 0,
        source_seq: 7,
        source_mono_ns: 0,
        poses_received: 1,
        extrapolated_s: 0.0,
        pose: PoseFields {
            seq: 7,
            t_ns: 0,
            position: [0.0, 0.0, 10.0],
            attitude: [0.0, 0.0, 0.0, 1.0],
            sun_dir: [0.0, 0.0, 1.0],
            velocity: None,
            angular_rate: None,
            camera_to_inertial: None,
            planet_centre: None,
        },
        settings: SettingsFields::from(&hilcam_core::render::integrator::RenderSettings::default()),
        flags: 0,
        late: false,
        extrapolated: false,
        degraded: false,
        integration_s: Some(0.001),
        payload_crc32: 585_609_882,
        request: Default::default(),
        mc_noise: Some(mc),
    };
    let encoded = SessionLine::Frame(frame.clone()).encode();
    assert!(encoded.ends_with(&format!(r#""payload_crc32":585609882,{object}}}"#)), "{encoded}");
    assert_eq!(SessionLine::decode(&encoded, Path::new("pin.session.jsonl"), 1).unwrap(), SessionLine::Frame(frame));
}
