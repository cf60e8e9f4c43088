#![no_main]
//! Arbitrary frame sequences on hilcam's ids: no panic; every pose that comes
//! out either passes validation or is rejected with a reason (never panics).
use hilcam_fuzz::pose::Message;
use hilcam_fuzz::pose::can::{CanAssembler, CanEvent, CanFrame, CanIds};
use hilcam_fuzz::pose::validate::{PoseLimits, PoseValidator};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut a = CanAssembler::new(CanIds::default());
    let mut v = PoseValidator::new(PoseLimits::default());
    let mut rest = data;
    // Each frame: [id offset, len/fd byte, data...]
    while rest.len() >= 2 {
        let off = (rest[0] % 0x14) as u32;
        let fd = rest[1] & 0x80 != 0;
        let len = (rest[1] & 0x7F) as usize % if fd { 65 } else { 9 };
        let body = &rest[2..rest.len().min(2 + len)];
        rest = &rest[(2 + len).min(rest.len())..];
        let f = if fd {
            CanFrame::new_fd(0x300 + off, false, body, true)
        } else {
            CanFrame::new(0x300 + off, false, body)
        };
        if let Some(f) = f {
            if let Some(CanEvent::Message(Message::Pose(p))) = a.push(&f) {
                if let Ok(ok) = v.check(&p) {
                    assert!((ok.attitude.length() - 1.0).abs() < 1e-9);
                    assert!(ok.position.is_finite());
                }
            }
        }
    }
});
