//! Every worked example in docs/protocol.md, read from the page itself and checked byte
//! for byte against hilcam's encoders: the documentation cannot drift from the program.

use crate::common;
use hilcam_core::pose::can::{self, CanIds};
use hilcam_core::pose::{Message, Pose, serial, slcan};

fn page() -> String {
    std::fs::read_to_string("docs/protocol.md").expect("docs/protocol.md")
}

/// The lines of the first fenced code block after the first line containing `marker`.
fn block_after(page: &str, marker: &str) -> Vec<String> {
    let start = page.find(marker).unwrap_or_else(|| panic!("docs/protocol.md has no `{marker}`"));
    let mut lines = page[start..].lines().skip_while(|l| !l.starts_with("```")).skip(1);
    lines.by_ref().take_while(|l| !l.starts_with("```")).map(str::to_string).collect()
}

/// Hex pairs of a documented dump line: the bytes before the comment (three spaces).
fn hex_bytes(text: &str) -> Vec<u8> {
    let data = text.split("   ").next().unwrap();
    data.split_whitespace()
        .map(|t| u8::from_str_radix(t, 16).unwrap_or_else(|_| panic!("`{t}` in `{text}` is not a hex byte")))
        .collect()
}

/// The backtick-quoted text on the line after `marker`.
fn quoted_after(page: &str, marker: &str) -> String {
    let start = page.find(marker).unwrap_or_else(|| panic!("docs/protocol.md has no `{marker}`"));
    let line = page[start..].lines().nth(1).unwrap();
    line.trim().trim_matches('`').to_string()
}

/// The page's example pose: seq 1, t = 123 456 789 ns, (0, 0, 10), identity, sun (0, 0, −1).
fn example_pose() -> Pose {
    Pose { seq: 1, t_ns: 123_456_789, ..Pose::ahead(10.0) }
}

#[test]
fn serial_pose_example_is_the_encoders_bytes_and_its_stated_length() {
    let p = page();
    let lines = block_after(&p, "no options — 106 bytes");
    let doc: Vec<u8> = lines.iter().flat_map(|l| hex_bytes(l)).collect();
    let enc = serial::encode_frame(&Message::Pose(example_pose()));
    assert_eq!(doc.len(), 106, "the example says 106 bytes");
    assert_eq!(doc, enc);
}

#[test]
fn serial_planet_example_is_the_encoders_bytes_and_decodes_to_its_planet() {
    let p = page();
    let lines = block_after(&p, "the Moon behind the\ntarget");
    let doc: Vec<u8> = lines.iter().flat_map(|l| hex_bytes(l)).collect();
    let pose = Pose { planet_centre: Some(glam::DVec3::new(0.0, 0.0, 3.844e8)), ..example_pose() };
    assert_eq!(doc.len(), 130, "the example says 130 bytes");
    assert_eq!(doc, serial::encode_frame(&Message::Pose(pose)));
    assert_eq!(serial::decode_frame(&doc), Ok((Message::Pose(pose), 130)));
    // Without the planet it is the 106-byte example: the block only appends.
    let plain = serial::encode_frame(&Message::Pose(example_pose()));
    assert_eq!((doc[18], plain[18]), (0x04, 0x00));
    assert_eq!(doc[19..102], plain[19..102]);
}

#[test]
fn serial_heartbeat_and_trigger_examples_are_the_encoders_bytes() {
    let p = page();
    let hb = hex_bytes(&quoted_after(&p, "Heartbeat, seq 7, t = 1 s, status 42:"));
    assert_eq!(hb, serial::encode_frame(&Message::Heartbeat { seq: 7, t_ns: 1_000_000_000, status: 42 }));
    let tr = hex_bytes(&quoted_after(&p, "Trigger, seq 8, t = 2.5 s:"));
    assert_eq!(tr, serial::encode_frame(&Message::Trigger { seq: 8, t_ns: 2_500_000_000 }));
}

#[test]
fn can_group_fd_and_slcan_examples_are_the_encoders_frames() {
    let p = page();
    let group = can::encode_group(CanIds::default(), &example_pose());
    let lines = block_after(&p, "as a group on base 0x300");
    assert_eq!(lines.len(), group.len());
    for (line, f) in lines.iter().zip(&group) {
        let frame = line.split_whitespace().next().unwrap();
        let (id, data) = frame.split_once('#').unwrap();
        assert_eq!(u32::from_str_radix(id, 16).unwrap(), f.id, "{line}");
        let bytes: Vec<u8> =
            (0..data.len()).step_by(2).map(|i| u8::from_str_radix(&data[i..i + 2], 16).unwrap()).collect();
        assert_eq!(bytes, f.data(), "{line}");
    }
    // CAN FD: `310##1 <hex groups> + 8×00`.
    let fd = can::encode_fd(CanIds::default(), &example_pose(), true).unwrap();
    let line = block_after(&p, "The same pose as CAN FD").into_iter().next().unwrap();
    let (id, rest) = line.split_once("##").unwrap();
    assert_eq!(u32::from_str_radix(id, 16).unwrap(), fd.id);
    let (hex, pad) = rest[1..].split_once('+').unwrap();
    let mut bytes: Vec<u8> = Vec::new();
    let digits: String = hex.split_whitespace().collect();
    for i in (0..digits.len()).step_by(2) {
        bytes.push(u8::from_str_radix(&digits[i..i + 2], 16).unwrap());
    }
    let zeros: usize = pad.trim().split('×').next().unwrap().parse().unwrap();
    bytes.extend(std::iter::repeat_n(0, zeros));
    assert_eq!(bytes, fd.data());
    // slcan: frame 0 of the group as a line.
    let start = p.find("the line `t").expect("slcan example");
    let quoted = p[start + "the line `".len()..].split('`').next().unwrap().replace("\\r", "\r");
    assert_eq!(quoted, slcan::encode_frame(&group[0]));
}

#[test]
fn frame_stream_example_is_the_encoders_bytes() {
    let p = page();
    let lines = block_after(&p, "`worked_example_encodes_to_documented_bytes`");
    let doc: Vec<u8> = lines.iter().flat_map(|l| hex_bytes(l.split_once(": ").unwrap().1)).collect();
    let frame = common::frames::example_frame();
    assert_eq!(doc, frame.encode().bytes);
}

/// The integers in the text after the first `marker` (up to `n` of them; `1 200` style
/// thousands are not used in these sentences).
fn numbers_after(page: &str, marker: &str, n: usize) -> Vec<usize> {
    let start = page.find(marker).unwrap_or_else(|| panic!("docs/protocol.md has no `{marker}`")) + marker.len();
    page[start..]
        .split(|c: char| !c.is_ascii_digit())
        .filter(|t| !t.is_empty())
        .take(n)
        .map(|t| t.parse().unwrap())
        .collect()
}

/// The example pose with no option, with velocity, with velocity and angular rate.
fn three_poses() -> [Pose; 3] {
    let v = Some(glam::DVec3::new(1.0, 2.0, 3.0));
    let w = Some(glam::DVec3::new(0.1, 0.2, 0.3));
    let p = example_pose();
    [p, Pose { velocity: v, ..p }, Pose { velocity: v, angular_rate: w, ..p }]
}

/// Issue 42: the lengths the page states are those of what the encoders produce.
#[test]
fn stated_lengths_are_the_encoders() {
    let p = page();
    // Serial: the three CAN poses and the last with the planet block too.
    let [a, b, c] = three_poses();
    let planet = Pose { planet_centre: Some(glam::DVec3::new(0.0, 0.0, 3.844e8)), ..c };
    let serial_len: Vec<usize> =
        [a, b, c, planet].iter().map(|q| serial::encode_frame(&Message::Pose(*q)).len()).collect();
    let n: Vec<usize> = serial_len.iter().map(|l| l - serial::HEADER_LEN - 4).collect();
    assert_eq!(numbers_after(&p, "**Pose payload** (type 1), N = ", 4), n, "pose payload lengths");
    assert_eq!(numbers_after(&p, "Bandwidth: a pose frame is ", 3), vec![serial_len[0], serial_len[2], serial_len[3]]);
    assert_eq!(numbers_after(&p, "for more than one maximum frame (", 1), vec![serial_len[3]]);
    assert_eq!(serial_len[3], serial::MAX_FRAME_LEN);
    let flags = [0, can::FLAG_VELOCITY, can::FLAG_VELOCITY | can::FLAG_ANGULAR_RATE];
    let block: Vec<usize> = flags.iter().map(|&f| can::block_len(f).unwrap()).collect();
    assert_eq!(numbers_after(&p, "Length ", 3), block, "compact block lengths");
    let frames: Vec<usize> = three_poses().iter().map(|q| can::encode_group(CanIds::default(), q).len()).collect();
    // "Group size: 6 frames (no options: 41 stream bytes), 8 frames (one option: 53 …"
    let stated = numbers_after(&p, "Group size: ", 6);
    assert_eq!([stated[0], stated[2], stated[4]].to_vec(), frames, "group frames");
    assert_eq!([stated[1], stated[3], stated[5]].to_vec(), block.iter().map(|b| b + 2).collect::<Vec<_>>());
    for (b, f) in block.iter().zip(&frames) {
        assert_eq!((b + 2).div_ceil(7), *f, "the stream bytes fill the frames");
    }
    let fd: Vec<usize> =
        three_poses().iter().map(|q| can::encode_fd(CanIds::default(), q, true).unwrap().data().len()).collect();
    let stated = numbers_after(&p, "One FD frame on `base + 0x10`: the group sequence byte, then the block;", 5);
    assert_eq!(&stated[..3], &block.iter().map(|b| b + 1).collect::<Vec<_>>()[..], "FD bytes before padding");
    assert_eq!(fd, vec![stated[3], stated[4], stated[4]], "padded FD lengths");
}
