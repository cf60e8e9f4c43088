#![no_main]
//! Arbitrary bytes in arbitrary chunks: no panic, bounded buffer, and every
//! decoded message re-encodes to a frame that decodes to the same message.
use hilcam_fuzz::pose::serial::{self, DecodeEvent, MAX_FRAME_LEN, SerialDecoder};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&step, rest)) = data.split_first() else {
        return;
    };
    let step = (step as usize % 64) + 1;
    let mut d = SerialDecoder::new();
    for chunk in rest.chunks(step) {
        d.push(chunk);
        while let Some(ev) = d.next_event() {
            if let DecodeEvent::Message(m) = ev {
                let f = serial::encode_frame(&m);
                let (again, n) = serial::decode_frame(&f).expect("re-encoded frame decodes");
                assert_eq!(n, f.len());
                // NaN != NaN: compare the bytes instead.
                assert_eq!(serial::encode_frame(&again), f);
            }
        }
        assert!(d.buffered() < MAX_FRAME_LEN + step);
    }
});
