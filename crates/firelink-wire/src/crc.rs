//! The IEEE 1394 CRC-32 (header CRC and data CRC).
//!
//! Generator `0x04C11DB7`, processed most significant bit first over the
//! big-endian wire bytes, initial value all ones, result complemented; not
//! reflected. This is the catalogue algorithm CRC-32/BZIP2
//! (`ieee1394.md`, "CRC"). [`crc1394`] takes headers and short blocks
//! eight bytes at a time through eight tables of this module, built at
//! compile time (a 12-byte header in about a third of the instructions the
//! `crc` crate's slice-by-16 spends on it, whose set-up outweighs its
//! width on so few bytes); from [`SIMD_MIN_LEN`] bytes on, with the default
//! feature `simd-crc`, the `crc-fast` crate folds the data with carry-less
//! multiplication where the CPU has it (about 4x the table on a 1 KiB hub
//! block, see `BENCHMARKS.md`), the tables otherwise. The incremental
//! [`Crc1394`] uses the `crc` crate's slice-by-16 table.
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
    !crc_by_eight(0xFFFF_FFFF, bytes)
}

/// The generator without its x^32 term.
const POLY: u32 = 0x04C1_1DB7;

/// `SLICES[k][b]`: what byte `b` followed by `k` zero bytes leaves in a
/// CRC register that held zero (most significant bit first, no final
/// complement). Row 0 is the classic byte-at-a-time table; row `k` is row
/// `k - 1` pushed through one more zero byte.
static SLICES: [[u32; 256]; 8] = slice_tables();

// Compile time only: an index out of range fails the build, it cannot
// panic at run time.
#[allow(clippy::indexing_slicing)]
const fn slice_tables() -> [[u32; 256]; 8] {
    let mut t = [[0u32; 256]; 8];
    let mut b = 0;
    while b < 256 {
        let mut reg = (b as u32) << 24;
        let mut bit = 0;
        while bit < 8 {
            reg = if reg & 0x8000_0000 != 0 {
                (reg << 1) ^ POLY
            } else {
                reg << 1
            };
            bit += 1;
        }
        t[0][b] = reg;
        b += 1;
    }
    let mut k = 1;
    while k < 8 {
        let mut b = 0;
        while b < 256 {
            let prev = t[k - 1][b];
            t[k][b] = (prev << 8) ^ t[0][(prev >> 24) as usize];
            b += 1;
        }
        k += 1;
    }
    t
}

/// Entry `index` of a table row (a byte's value: always in range; the
/// compiler sees it and drops the check).
#[inline(always)]
fn entry(row: &[u32; 256], index: u32) -> u32 {
    row.get(index as usize).copied().unwrap_or(0)
}

/// The CRC register after `bytes` are shifted into `reg` (no final
/// complement): eight bytes per step, then one quadlet, then single bytes.
#[inline]
fn crc_by_eight(mut reg: u32, bytes: &[u8]) -> u32 {
    let [t0, t1, t2, t3, t4, t5, t6, t7] = &SLICES;
    let mut octets = bytes.chunks_exact(8);
    for octet in &mut octets {
        let mut word = [0u8; 8];
        word.copy_from_slice(octet);
        let v = u64::from_be_bytes(word);
        let hi = (v >> 32) as u32 ^ reg;
        let lo = v as u32;
        reg = entry(t7, hi >> 24)
            ^ entry(t6, (hi >> 16) & 0xFF)
            ^ entry(t5, (hi >> 8) & 0xFF)
            ^ entry(t4, hi & 0xFF)
            ^ entry(t3, lo >> 24)
            ^ entry(t2, (lo >> 16) & 0xFF)
            ^ entry(t1, (lo >> 8) & 0xFF)
            ^ entry(t0, lo & 0xFF);
    }
    let mut rest = octets.remainder();
    if let Some((quad, tail)) = rest.split_first_chunk::<4>() {
        let x = u32::from_be_bytes(*quad) ^ reg;
        reg = entry(t3, x >> 24)
            ^ entry(t2, (x >> 16) & 0xFF)
            ^ entry(t1, (x >> 8) & 0xFF)
            ^ entry(t0, x & 0xFF);
        rest = tail;
    }
    for &byte in rest {
        reg = (reg << 8) ^ entry(t0, (reg >> 24) ^ u32::from(byte));
    }
    reg
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
    fn the_tables_match_the_bit_serial_reference_at_every_length() {
        // The table path on its own (also where the SIMD path would take
        // over), over the pseudo-random block, all ones and all zeros.
        let data: alloc_free::Bytes = alloc_free::Bytes::new();
        for len in 0..=data.len() {
            let bytes = data.get(..len).unwrap_or_default();
            assert_eq!(
                !crc_by_eight(0xFFFF_FFFF, bytes),
                crc1394_bitwise(bytes),
                "{len} bytes"
            );
        }
        for fill in [0x00u8, 0xFF, 0x80, 0x01] {
            let block = [fill; 70];
            for len in 0..=block.len() {
                let bytes = &block[..len];
                assert_eq!(
                    !crc_by_eight(0xFFFF_FFFF, bytes),
                    crc1394_bitwise(bytes),
                    "{len} bytes of {fill:#04x}"
                );
            }
        }
    }

    #[test]
    fn every_single_byte_value_matches_the_reference() {
        for b in 0..=255u8 {
            for len in 1..=9 {
                let mut block = [0u8; 9];
                block[len - 1] = b;
                let bytes = &block[..len];
                assert_eq!(crc1394(bytes), crc1394_bitwise(bytes), "{b:#04x} at {len}");
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
