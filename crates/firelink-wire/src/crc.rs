//! The IEEE 1394 CRC-32 (header CRC and data CRC).
//!
//! Generator `0x04C11DB7`, processed most significant bit first over the
//! big-endian wire bytes, initial value all ones, result complemented; not
//! reflected. This is the catalogue algorithm CRC-32/BZIP2
//! (`ieee1394.md`, "CRC"). Headers and short blocks go through a
//! slice-by-16 table (the `crc` crate); from [`SIMD_MIN_LEN`] bytes on, with
//! the default feature `simd-crc`, the `crc-fast` crate folds the data with
//! carry-less multiplication where the CPU has it (about 4x the table on a
//! 1 KiB hub block, see `BENCHMARKS.md`), the table otherwise.
//!
//! ```
//! use firelink_wire::crc::crc1394;
//! assert_eq!(crc1394(b"123456789"), 0xFC89_1918);
//! ```

use crc::{CRC_32_BZIP2, Crc, Table};

static CRC1394: Crc<u32, Table<16>> = Crc::<u32, Table<16>>::new(&CRC_32_BZIP2);

/// Blocks at least this long use the carry-less multiplication (shorter
/// ones are faster through the table: its set-up costs more than a header).
pub const SIMD_MIN_LEN: usize = 64;

/// The 1394 CRC of `bytes` (big-endian wire order).
pub fn crc1394(bytes: &[u8]) -> u32 {
    #[cfg(feature = "simd-crc")]
    if bytes.len() >= SIMD_MIN_LEN {
        return crc_fast::checksum(crc_fast::CrcAlgorithm::Crc32Bzip2, bytes) as u32;
    }
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
    fn every_length_matches_the_bit_serial_reference() {
        // Both sides of the table/SIMD threshold and the SIMD fold widths.
        let data: alloc_free::Bytes = alloc_free::Bytes::new();
        for len in 0..=data.len() {
            let bytes = data.get(..len).unwrap_or_default();
            assert_eq!(crc1394(bytes), crc1394_bitwise(bytes), "{len} bytes");
        }
    }

    /// A fixed pseudo-random block (no allocation: the crate is no_std).
    mod alloc_free {
        pub struct Bytes([u8; 1100]);
        impl Bytes {
            pub fn new() -> Bytes {
                let mut b = [0u8; 1100];
                let mut x = 0x1234_5678u32;
                for v in &mut b {
                    x ^= x << 13;
                    x ^= x >> 17;
                    x ^= x << 5;
                    *v = x as u8;
                }
                Bytes(b)
            }
            pub fn len(&self) -> usize {
                self.0.len()
            }
            pub fn get(&self, r: core::ops::RangeTo<usize>) -> Option<&[u8]> {
                self.0.get(r)
            }
        }
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
