//! The two checksums of the protocol (see `docs/protocol.md` for the choice).
//!
//! - Serial frames: CRC-32C (Castagnoli, reflected, init/xorout `0xFFFF_FFFF`),
//!   check value `0xE306_9283` for `"123456789"`.
//! - CAN classic groups: CRC-16/CCITT as CRC-16/IBM-3740 ("CCITT-FALSE": poly
//!   `0x1021`, init `0xFFFF`, not reflected), check value `0x29B1`; each CAN frame
//!   already carries the bus's own CRC-15, so the group CRC only has to catch
//!   assembly errors (frames of two groups mixed, stale or duplicated frames).

use crc::{CRC_16_IBM_3740, CRC_32_ISCSI, Crc};

const CRC32C: Crc<u32> = Crc::<u32>::new(&CRC_32_ISCSI);
const CRC16: Crc<u16> = Crc::<u16>::new(&CRC_16_IBM_3740);

/// CRC-32C of `bytes`.
pub fn crc32c(bytes: &[u8]) -> u32 {
    CRC32C.checksum(bytes)
}

/// CRC-16/CCITT-FALSE (IBM-3740) of `bytes`.
pub fn crc16_ccitt(bytes: &[u8]) -> u16 {
    CRC16.checksum(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    // Check values from the CRC catalogue (reveng), independent of the crc crate.
    #[test]
    fn catalogue_check_values() {
        assert_eq!(crc32c(b"123456789"), 0xE306_9283);
        assert_eq!(crc16_ccitt(b"123456789"), 0x29B1);
    }
}
