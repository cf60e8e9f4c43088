//! GVSP (GigE Vision Streaming Protocol) packets for one block: leader, payload
//! packets and trailer, at the negotiated packet size. Pure: the device shell sends
//! what [`Block::packet`] builds and keeps recent blocks for resends.
//!
//! Standard ids (16-bit block id, 24-bit packet id). Every packet starts with an 8-byte
//! header: status u16, block_id u16, then content type (8 bits) and packet id (24
//! bits). Packet 0 is the leader, 1..=n the payload, n+1 the trailer. Layouts as in
//! Aravis' `arvgvspprivate.h`; the byte tables are in `docs/gige.md`.

/// GVSP header bytes.
pub const HEADER_LEN: usize = 8;
/// IP + UDP header bytes, counted in the negotiated packet size (SCPS).
pub const IP_UDP_OVERHEAD: u32 = 28;
/// Leader packet length (header + image leader).
pub const LEADER_LEN: usize = HEADER_LEN + 36;
/// Trailer packet length.
pub const TRAILER_LEN: usize = HEADER_LEN + 8;

pub const CONTENT_LEADER: u8 = 0x01;
pub const CONTENT_TRAILER: u8 = 0x02;
pub const CONTENT_PAYLOAD: u8 = 0x03;

/// Packet status: sent normally.
pub const STATUS_SUCCESS: u16 = 0x0000;
/// Packet status: this packet answers a resend request.
pub const STATUS_RESEND: u16 = 0x0100;
/// Packet status: the requested packet is no longer (or never was) in the ring.
pub const STATUS_PACKET_UNAVAILABLE: u16 = 0x800C;

/// Payload type: an image.
pub const PAYLOAD_IMAGE: u16 = 0x0001;
/// Payload type flag: chunk data follows the image (extended chunk mode).
pub const PAYLOAD_CHUNK_FLAG: u16 = 0x4000;

/// Data bytes in one payload packet of a datagram of `packet_size` bytes.
pub fn data_per_packet(packet_size: u32) -> usize {
    packet_size.saturating_sub(IP_UDP_OVERHEAD + HEADER_LEN as u32).max(1) as usize
}

/// The next block id after `id` (16 bits; 0 is not a valid id).
pub fn next_block_id(id: u16) -> u16 {
    if id == u16::MAX { 1 } else { id + 1 }
}

/// One block: the image leader's fields and the bytes to send (pixels, then chunks).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Block {
    pub block_id: u16,
    /// Leader timestamp, ticks of the device clock (ns: the pose time).
    pub timestamp: u64,
    pub pixel_format: u32,
    pub width: u32,
    pub height: u32,
    pub offset_x: u32,
    pub offset_y: u32,
    /// [`PAYLOAD_IMAGE`], or with [`PAYLOAD_CHUNK_FLAG`] when chunks follow the pixels.
    pub payload_type: u16,
    pub data: Vec<u8>,
}

fn header(out: &mut Vec<u8>, status: u16, block_id: u16, content: u8, packet_id: u32) {
    out.extend_from_slice(&status.to_be_bytes());
    out.extend_from_slice(&block_id.to_be_bytes());
    out.extend_from_slice(&((u32::from(content) << 24) | (packet_id & 0x00FF_FFFF)).to_be_bytes());
}

impl Block {
    /// Payload packets at this packet size.
    pub fn payload_packets(&self, packet_size: u32) -> u32 {
        self.data.len().div_ceil(data_per_packet(packet_size)) as u32
    }

    /// All packets: leader + payload + trailer.
    pub fn packet_count(&self, packet_size: u32) -> u32 {
        self.payload_packets(packet_size) + 2
    }

    /// Packet `packet_id` with `status` ([`STATUS_SUCCESS`], or [`STATUS_RESEND`] when
    /// it answers a resend); None past the trailer.
    pub fn packet(&self, packet_id: u32, packet_size: u32, status: u16) -> Option<Vec<u8>> {
        let n = self.payload_packets(packet_size);
        let dpp = data_per_packet(packet_size);
        let mut out = Vec::with_capacity(HEADER_LEN + dpp);
        if packet_id == 0 {
            header(&mut out, status, self.block_id, CONTENT_LEADER, 0);
            out.extend_from_slice(&0u16.to_be_bytes()); // reserved
            out.extend_from_slice(&self.payload_type.to_be_bytes());
            out.extend_from_slice(&((self.timestamp >> 32) as u32).to_be_bytes());
            out.extend_from_slice(&(self.timestamp as u32).to_be_bytes());
            for v in [self.pixel_format, self.width, self.height, self.offset_x, self.offset_y] {
                out.extend_from_slice(&v.to_be_bytes());
            }
            out.extend_from_slice(&[0; 4]); // padding x, padding y
        } else if packet_id <= n {
            header(&mut out, status, self.block_id, CONTENT_PAYLOAD, packet_id);
            let start = (packet_id as usize - 1) * dpp;
            out.extend_from_slice(&self.data[start..(start + dpp).min(self.data.len())]);
        } else if packet_id == n + 1 {
            header(&mut out, status, self.block_id, CONTENT_TRAILER, packet_id);
            out.extend_from_slice(&0u16.to_be_bytes());
            out.extend_from_slice(&self.payload_type.to_be_bytes());
            out.extend_from_slice(&self.height.to_be_bytes());
        } else {
            return None;
        }
        Some(out)
    }
}

/// The answer to a resend of a packet that is not available.
pub fn unavailable_packet(block_id: u16, packet_id: u32) -> Vec<u8> {
    let mut out = Vec::with_capacity(HEADER_LEN);
    header(&mut out, STATUS_PACKET_UNAVAILABLE, block_id, CONTENT_PAYLOAD, packet_id);
    out
}

/// A parsed GVSP header (the client side: tests and the bench).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PacketHeader {
    pub status: u16,
    pub block_id: u16,
    pub content: u8,
    pub packet_id: u32,
}

pub fn parse_header(p: &[u8]) -> Option<PacketHeader> {
    if p.len() < HEADER_LEN {
        return None;
    }
    let infos = u32::from_be_bytes([p[4], p[5], p[6], p[7]]);
    Some(PacketHeader {
        status: u16::from_be_bytes([p[0], p[1]]),
        block_id: u16::from_be_bytes([p[2], p[3]]),
        content: (infos >> 24) as u8 & 0x7F,
        packet_id: infos & 0x00FF_FFFF,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn block(len: usize) -> Block {
        Block {
            block_id: 5,
            timestamp: 0x1_0000_0002,
            pixel_format: 0x0110_0007,
            width: 4,
            height: 2,
            offset_x: 0,
            offset_y: 0,
            payload_type: PAYLOAD_IMAGE,
            data: (0..len).map(|i| i as u8).collect(),
        }
    }

    #[test]
    fn packets_cover_the_data_at_the_packet_size() {
        // 576-byte datagrams carry 540 data bytes.
        let b = block(1000);
        assert_eq!(data_per_packet(576), 540);
        assert_eq!(b.packet_count(576), 4);
        let leader = b.packet(0, 576, STATUS_SUCCESS).unwrap();
        assert_eq!(leader.len(), LEADER_LEN);
        assert_eq!(parse_header(&leader).unwrap(), PacketHeader { status: 0, block_id: 5, content: 1, packet_id: 0 });
        assert_eq!(&leader[12..16], &1u32.to_be_bytes(), "timestamp high");
        let p1 = b.packet(1, 576, STATUS_SUCCESS).unwrap();
        let p2 = b.packet(2, 576, STATUS_RESEND).unwrap();
        assert_eq!(p1.len() - HEADER_LEN + p2.len() - HEADER_LEN, 1000);
        assert_eq!(parse_header(&p2).unwrap().status, STATUS_RESEND);
        assert_eq!(p2[HEADER_LEN], (540 % 256) as u8);
        let t = b.packet(3, 576, STATUS_SUCCESS).unwrap();
        assert_eq!(t.len(), TRAILER_LEN);
        assert_eq!(parse_header(&t).unwrap().content, CONTENT_TRAILER);
        assert!(b.packet(4, 576, STATUS_SUCCESS).is_none());
    }

    #[test]
    fn block_ids_skip_zero() {
        assert_eq!(next_block_id(u16::MAX), 1);
        assert_eq!(next_block_id(1), 2);
    }
}
