#![no_main]
//! Arbitrary blocks at arbitrary packet sizes: the packetiser never panics, its
//! payload packets carry the block's bytes exactly once and in order, every packet
//! fits the negotiated datagram, nothing exists past the trailer, and any bytes parse
//! (or not) as a GVSP header without a panic (what a client, or a hostile resend
//! answer, would meet).
use hilcam_fuzz::gvsp::{self, Block};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = gvsp::parse_header(data);
    if data.len() < 4 {
        return;
    }
    let size = 576 + 4 * (u32::from(u16::from_be_bytes([data[0], data[1]])) % ((9000 - 576) / 4 + 1));
    let block_id = gvsp::next_block_id(u16::from_be_bytes([data[2], data[3]]));
    let body = data[4..].to_vec();
    let block = Block {
        block_id,
        timestamp: 1,
        pixel_format: 0x0110_0007,
        width: 1,
        height: 1,
        offset_x: 0,
        offset_y: 0,
        payload_type: gvsp::PAYLOAD_IMAGE,
        data: body.clone(),
    };
    let n = block.packet_count(size);
    let mut joined = Vec::with_capacity(body.len());
    for pid in 0..n {
        let p = block.packet(pid, size, gvsp::STATUS_SUCCESS).expect("every id below the count exists");
        assert!(p.len() + gvsp::IP_UDP_OVERHEAD as usize <= size as usize);
        let h = gvsp::parse_header(&p).expect("our header parses");
        assert_eq!((h.block_id, h.packet_id), (block_id, pid));
        if h.content == gvsp::CONTENT_PAYLOAD {
            joined.extend_from_slice(&p[gvsp::HEADER_LEN..]);
        }
    }
    assert_eq!(joined, body, "payload packets carry the block exactly");
    assert!(block.packet(n, size, gvsp::STATUS_SUCCESS).is_none());
});
