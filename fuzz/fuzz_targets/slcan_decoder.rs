#![no_main]
//! Arbitrary adapter output: no panic; decoded frames re-encode to a line that
//! decodes to the same frame.
use hilcam_fuzz::pose::slcan::{self, SlcanDecoder, SlcanItem};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut d = SlcanDecoder::new();
    d.push(data);
    while let Some(item) = d.next_item() {
        if let Ok(SlcanItem::Frame(f)) = item {
            let line = slcan::encode_frame(&f);
            let again = slcan::decode_line(line.trim_end_matches('\r').as_bytes());
            assert_eq!(again, Ok(SlcanItem::Frame(f)));
        }
    }
});
