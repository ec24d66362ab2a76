//! The IEEE 1394 CRC-32 (header CRC and data CRC).
//!
//! Generator `0x04C11DB7`, processed most significant bit first over the
//! big-endian wire bytes, initial value all ones, result complemented; not
//! reflected. This is the catalogue algorithm CRC-32/BZIP2
//! (`ieee1394.md`, "CRC"). The implementation is a slice-by-16 table from the
//! `crc` crate, which runs at several GB/s on one core (see `BENCHMARKS.md`).
//!
//! ```
//! use firelink_wire::crc::crc1394;
//! assert_eq!(crc1394(b"123456789"), 0xFC89_1918);
//! ```

use crc::{CRC_32_BZIP2, Crc, Table};

static CRC1394: Crc<u32, Table<16>> = Crc::<u32, Table<16>>::new(&CRC_32_BZIP2);

/// The 1394 CRC of `bytes` (big-endian wire order).
pub fn crc1394(bytes: &[u8]) -> u32 {
    CRC1394.checksum(bytes)
}

/// The 1394 CRC of a sequence of quadlets given as host integers.
pub fn crc1394_quadlets(quadlets: &[u32]) -> u32 {
    let mut digest = Crc1394::new();
    for q in quadlets {
        digest.update(&q.to_be_bytes());
    }
    digest.finish()
}

/// Incremental 1394 CRC, for data that arrives in pieces.
pub struct Crc1394 {
    digest: crc::Digest<'static, u32, Table<16>>,
}

impl Crc1394 {
    /// Start a new CRC.
    pub fn new() -> Self {
        Crc1394 {
            digest: CRC1394.digest(),
        }
    }

    /// Feed more bytes.
    pub fn update(&mut self, bytes: &[u8]) {
        self.digest.update(bytes);
    }

    /// The CRC of everything fed so far.
    pub fn finish(self) -> u32 {
        self.digest.finalize()
    }
}

impl Default for Crc1394 {
    fn default() -> Self {
        Self::new()
    }
}

/// A bit-serial reference implementation, written directly from the
/// definition. Slow; used to cross-check the table implementation.
pub fn crc1394_bitwise(bytes: &[u8]) -> u32 {
    let mut crc: u32 = 0xFFFF_FFFF;
    for &byte in bytes {
        for bit in (0..8).rev() {
            let input = u32::from((byte >> bit) & 1);
            let top = crc >> 31;
            crc <<= 1;
            if top ^ input == 1 {
                crc ^= 0x04C1_1DB7;
            }
        }
    }
    !crc
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_value() {
        assert_eq!(crc1394(b"123456789"), 0xFC89_1918);
        assert_eq!(crc1394_bitwise(b"123456789"), 0xFC89_1918);
    }

    #[test]
    fn incremental_matches_one_shot() {
        let data: [u8; 13] = *b"hello, 1394!!";
        let mut d = Crc1394::new();
        d.update(&data[..5]);
        d.update(&data[5..]);
        assert_eq!(d.finish(), crc1394(&data));
    }
}
