//! Codec tests from byte literals (CRCs computed by an independent bitwise
//! implementation, not the `crc` crate), plus property-based round trips.

use glam::{DQuat, DVec3};
use hilcam_core::pose::can::{self, CanAssembler, CanEvent, CanFrame, CanIds, GroupDrop};
use hilcam_core::pose::serial::{self, DecodeEvent, FrameError, Malformed, SerialDecoder};
use hilcam_core::pose::slcan::{self, SlcanDecoder, SlcanError, SlcanItem};
use hilcam_core::pose::{Message, Pose};
use proptest::prelude::*;

fn unhex(s: &str) -> Vec<u8> {
    let s: String = s.split_whitespace().collect();
    (0..s.len()).step_by(2).map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap()).collect()
}

const POSE_FRAME: &str = "a55a010154000100000015cd5b07000000000000000000000000000000000000 0000000000000000000000002440000000000000f03f00000000000000000000 0000000000000000000000000000000000000000000000000000000000000000 00000000f0bfd32e98c0";

fn literal_pose() -> Pose {
    Pose { seq: 1, t_ns: 123_456_789, ..Pose::ahead(10.0) }
}

#[test]
fn serial_literals_decode_and_encode_bit_exactly() {
    let cases = [
        (POSE_FRAME.to_string(), Message::Pose(literal_pose())),
        (
            "a5 5a 01 03 04 00 07 00 00 00 00 ca 9a 3b 00 00 00 00 2a 00 00 00 11 76 4b 3c".into(),
            Message::Heartbeat { seq: 7, t_ns: 1_000_000_000, status: 42 },
        ),
        (
            "a5 5a 01 02 00 00 08 00 00 00 00 f9 02 95 00 00 00 00 39 de ac 1b".into(),
            Message::Trigger { seq: 8, t_ns: 2_500_000_000 },
        ),
    ];
    for (hex, msg) in cases {
        let bytes = unhex(&hex);
        assert_eq!(serial::decode_frame(&bytes), Ok((msg, bytes.len())));
        assert_eq!(serial::encode_frame(&msg), bytes);
        // Every strict prefix is "need more", never "malformed".
        for n in 0..bytes.len() {
            assert!(
                matches!(serial::decode_frame(&bytes[..n]), Err(FrameError::Incomplete { needed }) if needed > n),
                "prefix {n}"
            );
        }
    }
}

#[test]
fn serial_malformed_kinds() {
    let good = unhex(POSE_FRAME);
    let m = |b: &[u8]| match serial::decode_frame(b) {
        Err(FrameError::Malformed(k)) => k,
        other => panic!("expected malformed, got {other:?}"),
    };
    assert_eq!(m(&[0x00]), Malformed::NoSync);
    assert_eq!(m(&[0xA5, 0x00]), Malformed::NoSync);
    let mut b = good.clone();
    b[2] = 2;
    assert_eq!(m(&b), Malformed::BadVersion(2));
    b = good.clone();
    b[3] = 9;
    assert_eq!(m(&b), Malformed::UnknownType(9));
    b = good.clone();
    b[4] = 0xFF; // length 0x54 → 0xFF: impossible for a pose, rejected before waiting
    assert_eq!(m(&b[..6]), Malformed::BadLength { ty: 1, len: 0xFF });
    b = good.clone();
    b[40] ^= 0x01;
    assert!(matches!(m(&b), Malformed::Crc { .. }));
    // Valid CRC but a reserved byte set: a sender bug, still malformed.
    b = good.clone();
    b[19] = 1;
    let crc = hilcam_core::pose::crc::crc32c(&b[2..b.len() - 4]);
    let n = b.len();
    b[n - 4..].copy_from_slice(&crc.to_le_bytes());
    assert_eq!(m(&b), Malformed::BadFlags(0));
}

#[test]
fn decoder_resyncs_and_counts_garbage() {
    let frame = unhex(POSE_FRAME);
    let mut stream = b"\x00garbage\xA5\x5A\x01".to_vec(); // includes a false sync
    stream.extend_from_slice(&frame);
    stream.extend_from_slice(&[0xA5]); // trailing partial sync stays buffered
    let mut d = SerialDecoder::new();
    // Byte at a time: partial writes must not matter.
    let mut msgs = vec![];
    let mut discarded = 0;
    for b in &stream {
        d.push(std::slice::from_ref(b));
        while let Some(ev) = d.next_event() {
            match ev {
                DecodeEvent::Message(m) => msgs.push(m),
                DecodeEvent::Discarded { bytes, .. } => discarded += bytes,
            }
        }
    }
    assert_eq!(msgs, vec![Message::Pose(literal_pose())]);
    assert_eq!(discarded, 11);
    assert_eq!(d.stats().discarded_bytes, 11);
    assert_eq!(d.buffered(), 1);
}

#[test]
fn a_planet_block_appends_24_bytes_and_a_corrupted_or_inconsistent_one_is_malformed() {
    let plain = unhex(POSE_FRAME);
    let moon = Pose { planet_centre: Some(DVec3::new(-1.5e3, 2.0e7, 3.844e8)), ..literal_pose() };
    let b = serial::encode_frame(&Message::Pose(moon));
    // Built here from the layout: flags 0x04, N = 108, the planet's f64s after the sun.
    let mut want = plain[..plain.len() - 4].to_vec();
    want[4] = 108;
    want[18] = 0x04;
    for c in [-1.5e3f64, 2.0e7, 3.844e8] {
        want.extend_from_slice(&c.to_le_bytes());
    }
    let crc = hilcam_core::pose::crc::crc32c(&want[2..]);
    want.extend_from_slice(&crc.to_le_bytes());
    assert_eq!(b, want);
    assert_eq!(serial::decode_frame(&b), Ok((Message::Pose(moon), 130)));
    let m = |b: &[u8]| match serial::decode_frame(b) {
        Err(FrameError::Malformed(k)) => k,
        other => panic!("expected malformed, got {other:?}"),
    };
    // One bit of plz flipped on the line: the CRC catches it.
    let mut bad = b.clone();
    bad[18 + 84 + 20] ^= 0x01;
    assert!(matches!(m(&bad), Malformed::Crc { .. }));
    // A valid CRC over an inconsistent frame (flag without the block, block without the
    // flag, an unknown flag): a sender bug, malformed.
    let recrc = |mut v: Vec<u8>| {
        let n = v.len();
        let crc = hilcam_core::pose::crc::crc32c(&v[2..n - 4]);
        v[n - 4..].copy_from_slice(&crc.to_le_bytes());
        v
    };
    let mut flag_only = plain.clone();
    flag_only[18] = 0x04;
    assert_eq!(m(&recrc(flag_only)), Malformed::BadFlags(0x04));
    let mut block_only = b.clone();
    block_only[18] = 0x00;
    assert_eq!(m(&recrc(block_only)), Malformed::BadFlags(0x00));
    let mut unknown = b.clone();
    unknown[18] = 0x0C;
    assert_eq!(m(&recrc(unknown)), Malformed::BadFlags(0x0C));
    // In a stream: the corrupted frame is counted as a CRC failure and skipped, the next
    // frame decodes.
    let mut d = SerialDecoder::new();
    d.push(&bad);
    d.push(&b);
    let mut msgs = vec![];
    while let Some(ev) = d.next_event() {
        if let DecodeEvent::Message(msg) = ev {
            msgs.push(msg);
        }
    }
    assert_eq!(msgs, vec![Message::Pose(moon)]);
    assert_eq!(d.stats().crc_failures, 1);
}

const GROUP: [(u32, &str); 6] = [
    (0x300, "010015cd5b070000"),
    (0x301, "0100000000000000"),
    (0x302, "0100000000002041"),
    (0x303, "01ffff7f00000000"),
    (0x304, "0100000000000000"),
    (0x305, "0100000180a4b200"),
];

fn group_frames() -> Vec<CanFrame> {
    GROUP.iter().map(|(id, h)| CanFrame::new(*id, false, &unhex(h)).unwrap()).collect()
}

#[test]
fn can_group_literal_decodes_and_encodes() {
    let ids = CanIds::default();
    assert_eq!(can::encode_group(ids, &literal_pose()), group_frames());
    let mut a = CanAssembler::new(ids);
    let frames = group_frames();
    for f in &frames[..5] {
        assert_eq!(a.push(f), None);
    }
    let Some(CanEvent::Message(Message::Pose(p))) = a.push(&frames[5]) else { panic!() };
    // Position (0,0,10) and the unit quaternion/sun are exact in f32/Q23/Q15 up to 1 step.
    assert_eq!(p.position, DVec3::new(0.0, 0.0, 10.0));
    assert_eq!(p.t_ns, 123_456_789);
    assert!((p.attitude.w - 1.0).abs() < 1.2e-7);
    assert!((p.sun_dir.z + 1.0).abs() < 3.1e-5);
    assert_eq!(p.seq, 1);
}

#[test]
fn can_fd_literal() {
    let hex = "010015cd5b0700000000000000000000000000002041ffff7f000000000000000000000000000180";
    let f = can::encode_fd(CanIds::default(), &literal_pose(), true).unwrap();
    assert_eq!(f.id, 0x310);
    assert_eq!(f.data().len(), 48); // 40 bytes padded to the next FD length
    assert_eq!(&f.data()[..40], unhex(hex).as_slice());
    assert!(f.data()[40..].iter().all(|&b| b == 0));
    let p = can::decode_fd(f.data()).unwrap();
    assert_eq!(p.position.z, 10.0);
}

#[test]
fn can_groups_with_missing_mixed_duplicate_or_corrupt_frames_are_dropped() {
    let ids = CanIds::default();
    let g1 = group_frames();
    let g2 = can::encode_group(ids, &Pose { seq: 2, ..literal_pose() });
    let run = |frames: &[CanFrame]| {
        let mut a = CanAssembler::new(ids);
        let mut evs: Vec<CanEvent> = frames.iter().filter_map(|f| a.push(f)).collect();
        evs.extend(a.flush());
        evs
    };
    let ok = CanEvent::Message(Message::Pose(Pose {
        seq: 2,
        ..can::decode_fd(can::encode_fd(ids, &Pose { seq: 2, ..literal_pose() }, false).unwrap().data()).unwrap()
    }));
    // Missing frame 3 of group 1, then group 2 complete.
    let mut s: Vec<CanFrame> = g1.iter().enumerate().filter(|(i, _)| *i != 3).map(|(_, f)| *f).collect();
    s.extend(&g2);
    assert_eq!(run(&s), vec![CanEvent::Dropped(GroupDrop::MissingFrame), ok]);
    // A frame of group 2 in the middle of group 1.
    let mut s = g1[..3].to_vec();
    s.push(g2[3]);
    s.extend(&g1[3..]);
    let evs = run(&s);
    assert_eq!(evs[0], CanEvent::Dropped(GroupDrop::MixedSequence));
    assert!(!evs.iter().any(|e| matches!(e, CanEvent::Message(_))), "{evs:?}");
    // Duplicate frame.
    let mut s = g1[..2].to_vec();
    s.push(g1[1]);
    assert_eq!(run(&s)[0], CanEvent::Dropped(GroupDrop::DuplicateFrame));
    // Corrupted data byte: group CRC catches it.
    let mut s = g1.clone();
    let mut d = s[2].data().to_vec();
    d[5] ^= 0x10;
    s[2] = CanFrame::new(s[2].id, false, &d).unwrap();
    assert_eq!(run(&s), vec![CanEvent::Dropped(GroupDrop::Crc)]);
    // Wrong DLC.
    assert_eq!(run(&[CanFrame::new(0x300, false, &[1, 0]).unwrap()]), vec![CanEvent::Dropped(GroupDrop::BadLength(2))]);
    // Other traffic is ignored, not an error.
    let mut a = CanAssembler::new(ids);
    assert_eq!(a.push(&CanFrame::new(0x123, false, &[0; 8]).unwrap()), None);
    assert_eq!(a.push(&CanFrame::new(0x300, true, &[0; 8]).unwrap()), None);
    assert_eq!(a.foreign_frames(), 2);
}

#[test]
fn a_can_planet_block_adds_12_bytes_and_a_corrupted_one_is_dropped() {
    let ids = CanIds::default();
    let base = Pose { velocity: Some(DVec3::X), angular_rate: Some(DVec3::Y), ..literal_pose() };
    let with = Pose { planet_centre: Some(DVec3::new(-1.25e7, 3.5e6, 3.844e8)), ..base };
    // 39 + 12 + 12 + 12 block bytes + CRC-16 = 77 stream bytes: 11 frames on base + 0 … 10.
    let g = can::encode_group(ids, &with);
    assert_eq!((can::encode_group(ids, &base).len(), g.len()), (10, 11));
    assert_eq!(g.last().unwrap().id, ids.base() + 10);
    assert_eq!(g[0].data()[1], can::FLAG_VELOCITY | can::FLAG_ANGULAR_RATE | can::FLAG_PLANET);
    let mut a = CanAssembler::new(ids);
    let got: Vec<CanEvent> = g.iter().filter_map(|f| a.push(f)).collect();
    let [CanEvent::Message(Message::Pose(p))] = got[..] else { panic!("{got:?}") };
    assert_eq!(p.planet_centre, Some(DVec3::new(-1.25e7, 3.5e6, 3.844e8f32 as f64)));
    // A flipped bit in the planet's bytes (frame 9) fails the group CRC: dropped, counted.
    let mut bad = g.clone();
    let mut d = [0u8; 8];
    d.copy_from_slice(bad[9].data());
    d[3] ^= 0x10;
    bad[9] = CanFrame::new(bad[9].id, false, &d).unwrap();
    let got: Vec<CanEvent> = bad.iter().filter_map(|f| a.push(f)).collect();
    assert_eq!(got, vec![CanEvent::Dropped(GroupDrop::Crc)]);
    // FD: a planet with one rate fits (64 bytes); with both it does not.
    let one = Pose { angular_rate: None, ..with };
    let f = can::encode_fd(ids, &one, true).unwrap();
    assert_eq!(f.data().len(), 64);
    assert_eq!(can::decode_fd(f.data()).unwrap().planet_centre, p.planet_centre);
    assert!(can::encode_fd(ids, &with, true).is_none() && !can::fits_fd(&with));
}

#[test]
fn can_trigger_heartbeat_and_ids() {
    let ids = CanIds::new(0x1ABC_DE00, true).unwrap();
    let mut a = CanAssembler::new(ids);
    for msg in [Message::Trigger { seq: 0, t_ns: 77 }, Message::Heartbeat { seq: 5, t_ns: 0, status: 3 }] {
        let f = can::encode_message(ids, &msg, false);
        assert_eq!(f.len(), 1);
        assert_eq!(a.push(&f[0]), Some(CanEvent::Message(msg)));
    }
    assert!(CanIds::new(0x7F0, false).is_err());
    assert!(CanIds::new(0x7EF, false).is_ok());
}

#[test]
fn slcan_lines() {
    let f = CanFrame::new(0x301, false, &[0x01, 0xAB]).unwrap();
    assert_eq!(slcan::encode_frame(&f), "t301201AB\r");
    assert_eq!(slcan::decode_line(b"t301201AB"), Ok(SlcanItem::Frame(f)));
    assert_eq!(slcan::decode_line(b"t301201AB1234"), Ok(SlcanItem::Frame(f)), "timestamp");
    let e = CanFrame::new(0x1ABCDE01, true, &[]).unwrap();
    assert_eq!(slcan::encode_frame(&e), "T1ABCDE010\r");
    let fd = CanFrame::new_fd(0x310, false, &[7; 10], true).unwrap();
    assert_eq!(fd.data().len(), 12);
    let line = slcan::encode_frame(&fd);
    assert!(line.starts_with("b3109"), "{line}");
    assert_eq!(slcan::decode_line(line.trim_end().as_bytes()), Ok(SlcanItem::Frame(fd)));
    assert_eq!(slcan::decode_line(b""), Ok(SlcanItem::Ack));
    assert_eq!(slcan::decode_line(b"r3010"), Ok(SlcanItem::Remote { id: 0x301 }));
    assert_eq!(slcan::decode_line(b"x"), Err(SlcanError::UnknownCommand(b'x')));
    assert_eq!(slcan::decode_line(b"t3012G1AB"), Err(SlcanError::BadHex));
    assert_eq!(slcan::decode_line(b"t3019"), Err(SlcanError::BadFrame));
    assert_eq!(slcan::decode_line(b"t3012AB"), Err(SlcanError::BadFrame));
    let mut d = SlcanDecoder::new();
    d.push(b"\x07t3012\n01AB\r");
    assert_eq!(d.next_item(), Some(Ok(SlcanItem::Nack)));
    assert_eq!(d.next_item(), Some(Ok(SlcanItem::Frame(f))));
    d.push(&[b'0'; 200]);
    d.push(b"\r");
    assert_eq!(d.next_item(), Some(Err(SlcanError::TooLong)));
    assert_eq!(slcan::bitrate_code(500_000), Some(6));
    assert_eq!(slcan::bitrate_code(1_000_000), Some(8));
    assert_eq!(slcan::bitrate_code(333_000), None);
}

fn unit_quat() -> impl Strategy<Value = DQuat> {
    (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64)
        .prop_filter("non-degenerate", |(w, x, y, z)| w * w + x * x + y * y + z * z > 0.01)
        .prop_map(|(w, x, y, z)| DQuat::from_xyzw(x, y, z, w).normalize())
}

fn unit_vec() -> impl Strategy<Value = DVec3> {
    (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64)
        .prop_filter("non-degenerate", |(x, y, z)| x * x + y * y + z * z > 0.01)
        .prop_map(|(x, y, z)| DVec3::new(x, y, z).normalize())
}

fn opt_vec(scale: f64) -> impl Strategy<Value = Option<DVec3>> {
    proptest::option::of((-scale..scale, -scale..scale, -scale..scale).prop_map(|(x, y, z)| DVec3::new(x, y, z)))
}

prop_compose! {
    fn any_pose()(seq in any::<u32>(), t_ns in any::<u64>(),
                  r in 0.1..1.0e6f64, dir in unit_vec(), q in unit_quat(), sun in unit_vec(),
                  v in opt_vec(100.0), w in opt_vec(1.0)) -> Pose {
        Pose { seq, t_ns, position: dir * r, attitude: q, sun_dir: sun, velocity: v, angular_rate: w, camera_to_inertial: None, planet_centre: None }
    }
}

proptest! {
    #[test]
    fn serial_round_trip_is_exact(p in any_pose(), split in 0usize..200) {
        let msg = Message::Pose(p);
        let bytes = serial::encode_frame(&msg);
        let mut d = SerialDecoder::new();
        let k = split.min(bytes.len());
        d.push(&bytes[..k]);
        if k < bytes.len() { prop_assert_eq!(d.next_event(), None); }
        d.push(&bytes[k..]);
        prop_assert_eq!(d.next_event(), Some(DecodeEvent::Message(msg)));
        prop_assert_eq!(d.next_event(), None);
    }

    #[test]
    fn serial_round_trip_with_a_planet_is_exact(p in any_pose(), c in opt_vec(1.5e13)) {
        let msg = Message::Pose(Pose { planet_centre: c, ..p });
        let bytes = serial::encode_frame(&msg);
        prop_assert_eq!(bytes.len(), 106 + 24 * [p.velocity.is_some(), p.angular_rate.is_some(), c.is_some()].iter().filter(|x| **x).count());
        prop_assert_eq!(serial::decode_frame(&bytes), Ok((msg, bytes.len())));
    }

    #[test]
    fn can_round_trip_with_a_planet_keeps_f32_precision(p in any_pose(), c in opt_vec(1.5e13), fd in any::<bool>()) {
        // Classic groups carry every pose (up to 11 frames); an FD frame all but both rates
        // with a planet, which `encode_message` then sends as a classic group.
        let p = Pose { planet_centre: c, ..p };
        let ids = CanIds::default();
        let frames = can::encode_message(ids, &Message::Pose(p), fd);
        let all_three = p.velocity.is_some() && p.angular_rate.is_some() && c.is_some();
        prop_assert_eq!(can::fits_fd(&p), !all_three);
        prop_assert_eq!(frames.len() == 1, fd && !all_three);
        prop_assert!(frames.len() <= can::MAX_GROUP_FRAMES);
        let mut a = CanAssembler::new(ids);
        let got: Vec<CanEvent> = frames.iter().filter_map(|f| a.push(f)).collect();
        prop_assert_eq!(got.len(), 1);
        let CanEvent::Message(Message::Pose(g)) = got[0] else { panic!("{:?}", got) };
        prop_assert_eq!(g.planet_centre.is_some(), c.is_some());
        if let (Some(a), Some(b)) = (g.planet_centre, c) {
            // f32 per component: within 2^-24 of the largest (its angular error at any range).
            prop_assert!((a - b).abs().max_element() <= b.abs().max_element() * 6.0e-8, "{} vs {}", a, b);
        }
    }

    #[test]
    fn can_round_trip_within_documented_precision(p in any_pose(), fd in any::<bool>()) {
        let ids = CanIds::default();
        let mut a = CanAssembler::new(ids);
        let got: Vec<CanEvent> = can::encode_message(ids, &Message::Pose(p), fd).iter().filter_map(|f| a.push(f)).collect();
        prop_assert_eq!(got.len(), 1);
        let CanEvent::Message(Message::Pose(g)) = got[0] else { panic!("{:?}", got) };
        prop_assert_eq!(g.seq, p.seq & 0xFF);
        prop_assert_eq!(g.t_ns, p.t_ns);
        // f32: relative error ≤ 2^-24 per component.
        prop_assert!((g.position - p.position).abs().max_element() <= p.position.abs().max_element() * 6.0e-8);
        // Q23 / Q15: half a step per component.
        let dq = [g.attitude.w - p.attitude.w, g.attitude.x - p.attitude.x, g.attitude.y - p.attitude.y, g.attitude.z - p.attitude.z];
        prop_assert!(dq.iter().all(|d| d.abs() <= 0.5 / can::QUAT_SCALE + 1e-12));
        prop_assert!((g.sun_dir - p.sun_dir).abs().max_element() <= 0.5 / can::SUN_SCALE + 1e-12);
        prop_assert_eq!(g.velocity.is_some(), p.velocity.is_some());
        prop_assert_eq!(g.angular_rate.is_some(), p.angular_rate.is_some());
        if let (Some(a), Some(b)) = (g.angular_rate, p.angular_rate) {
            prop_assert!((a - b).abs().max_element() <= 6.0e-8);
        }
    }

    #[test]
    fn slcan_round_trip(id in 0u32..0x800, ext in any::<bool>(), data in proptest::collection::vec(any::<u8>(), 0..=64), fd in any::<bool>(), brs in any::<bool>()) {
        let id = if ext { id * 0x3FFF } else { id };
        let f = if fd { CanFrame::new_fd(id, ext, &data, brs) } else { CanFrame::new(id, ext, &data[..data.len().min(8)]) }.unwrap();
        let line = slcan::encode_frame(&f);
        let mut d = SlcanDecoder::new();
        d.push(line.as_bytes());
        prop_assert_eq!(d.next_item(), Some(Ok(SlcanItem::Frame(f))));
    }
}
