//! CAN 2.0A frames at the bit level: the fields, the CRC-15, bit stuffing
//! and the exact number of bits a frame occupies on the bus.
//!
//! A standard (11-bit identifier) data or remote frame is, in order:
//!
//! | field | bits | stuffed? |
//! |---|---|---|
//! | start of frame (dominant) | 1 | yes |
//! | identifier | 11 | yes |
//! | RTR, IDE, r0 | 3 | yes |
//! | data length code | 4 | yes |
//! | data (none in a remote frame) | 8 n | yes |
//! | CRC-15 | 15 | yes |
//! | CRC delimiter, ACK slot, ACK delimiter | 3 | no |
//! | end of frame | 7 | no |
//! | intermission | 3 | no |
//!
//! so `47 + 8 n` bits before stuffing; after five equal bits in the stuffed
//! part the transmitter inserts one of the other value, which can add up
//! to `floor((34 + 8 n - 1) / 4)` bits: the worst case `8 n + 47 +
//! floor((34 + 8 n - 1) / 4)` (Davis, Burns, Bril and Lukkien, "Controller
//! Area Network (CAN) schedulability analysis", 2007), 135 bits for 8 data
//! bytes. [`Frame::bits`] counts the exact bits of one frame.

use crate::{CanError, Result};

/// An 11-bit identifier: the frame's priority (lower wins arbitration).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct CanId(u16);

impl CanId {
    /// The largest standard identifier.
    pub const MAX: u16 = 0x7FF;

    /// An identifier.
    ///
    /// # Errors
    /// [`CanError::Identifier`] above [`CanId::MAX`].
    pub fn new(id: u16) -> Result<CanId> {
        if id > Self::MAX {
            return Err(CanError::Identifier(id));
        }
        Ok(CanId(id))
    }

    /// The raw 11 bits.
    pub fn raw(self) -> u16 {
        self.0
    }
}

/// One CAN 2.0A frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Frame {
    id: CanId,
    remote: bool,
    len: u8,
    data: [u8; 8],
}

/// Bits of a frame before stuffing: SOF to the end of the CRC (`34 + 8 n`)
/// are stuffed, the 13 after it are not.
const UNSTUFFED_TAIL: usize = 3 + 7 + 3;
/// Bits of the stuffed part without data.
const STUFFED_FIXED: usize = 1 + 11 + 3 + 4 + 15;

/// The CAN CRC-15 generator, x^15 + x^14 + x^10 + x^8 + x^7 + x^4 + x^3 + 1.
pub const CRC15_POLY: u16 = 0x4599;

/// CRC-15 of a bit sequence (one bit per element, first bit first).
pub fn crc15(bits: impl IntoIterator<Item = bool>) -> u16 {
    let mut crc: u16 = 0;
    for bit in bits {
        let next = bit ^ (crc & 0x4000 != 0);
        crc = (crc << 1) & 0x7FFF;
        if next {
            crc ^= CRC15_POLY;
        }
    }
    crc
}

/// Stuff bits a transmitter inserts into `bits` (one after every run of
/// five equal bits; the stuff bit starts the next run).
pub fn stuff_bits(bits: impl IntoIterator<Item = bool>) -> usize {
    let mut count = 0;
    let mut run = 0;
    let mut last = None;
    for bit in bits {
        if Some(bit) == last {
            run += 1;
        } else {
            run = 1;
            last = Some(bit);
        }
        if run == 5 {
            count += 1;
            // The stuff bit is the opposite value and starts a new run.
            last = Some(!bit);
            run = 1;
        }
    }
    count
}

/// The worst-case length in bits of a standard frame with `n` data bytes,
/// intermission included: `8 n + 47 + floor((34 + 8 n - 1) / 4)`.
pub fn worst_case_bits(n: usize) -> usize {
    let n = n.min(8);
    8 * n + 47 + (STUFFED_FIXED + 8 * n - 1) / 4
}

impl Frame {
    /// A data frame with up to 8 bytes.
    ///
    /// # Errors
    /// [`CanError::Length`] for more than 8 bytes.
    pub fn data(id: CanId, data: &[u8]) -> Result<Frame> {
        let mut buf = [0u8; 8];
        buf.get_mut(..data.len())
            .ok_or(CanError::Length(data.len()))?
            .copy_from_slice(data);
        Ok(Frame {
            id,
            remote: false,
            len: data.len() as u8,
            data: buf,
        })
    }

    /// A remote frame asking for `len` bytes (0..=8).
    ///
    /// # Errors
    /// [`CanError::Length`] for more than 8.
    pub fn remote(id: CanId, len: u8) -> Result<Frame> {
        if len > 8 {
            return Err(CanError::Length(usize::from(len)));
        }
        Ok(Frame {
            id,
            remote: true,
            len,
            data: [0; 8],
        })
    }

    /// Its identifier.
    pub fn id(&self) -> CanId {
        self.id
    }

    /// Whether it is a remote frame.
    pub fn is_remote(&self) -> bool {
        self.remote
    }

    /// Its data (empty for a remote frame).
    pub fn payload(&self) -> &[u8] {
        if self.remote {
            &[]
        } else {
            self.data.get(..usize::from(self.len)).unwrap_or(&[])
        }
    }

    /// The data length code.
    pub fn dlc(&self) -> u8 {
        self.len
    }

    /// The bits from start of frame to the end of the data, unstuffed
    /// (what the CRC covers).
    pub fn header_and_data_bits(&self) -> impl Iterator<Item = bool> + '_ {
        let field = |value: u32, width: u32| (0..width).rev().map(move |i| value >> i & 1 != 0);
        let sof = core::iter::once(false);
        let id = field(u32::from(self.id.0), 11);
        // RTR, IDE (standard: dominant), r0 (dominant).
        let control = [self.remote, false, false].into_iter();
        let dlc = field(u32::from(self.len), 4);
        let data = self
            .payload()
            .iter()
            .flat_map(move |b| field(u32::from(*b), 8));
        sof.chain(id).chain(control).chain(dlc).chain(data)
    }

    /// Its CRC-15.
    pub fn crc(&self) -> u16 {
        crc15(self.header_and_data_bits())
    }

    /// The stuffed part of the frame, unstuffed: SOF to the end of the CRC.
    pub fn stuffed_part(&self) -> impl Iterator<Item = bool> + '_ {
        let crc = self.crc();
        self.header_and_data_bits()
            .chain((0..15).rev().map(move |i| crc >> i & 1 != 0))
    }

    /// Stuff bits this frame gets.
    pub fn stuff_bits(&self) -> usize {
        stuff_bits(self.stuffed_part())
    }

    /// Exact bits on the bus, intermission included: `47 + 8 n + stuff`.
    pub fn bits(&self) -> usize {
        STUFFED_FIXED + 8 * self.payload().len() + self.stuff_bits() + UNSTUFFED_TAIL
    }

    /// Bits on the bus up to the end of the frame (without the
    /// intermission): when receivers have it.
    pub fn bits_to_end_of_frame(&self) -> usize {
        self.bits() - 3
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn worst_case_formula() {
        assert_eq!(worst_case_bits(0), 55);
        assert_eq!(worst_case_bits(8), 135);
        for n in 0..=8 {
            assert_eq!(
                worst_case_bits(n),
                55 + 10 * n,
                "Davis et al.: (55 + 10 n) bits"
            );
        }
    }

    #[test]
    fn stuffing_counts_runs() {
        let bits = |s: &str| s.chars().map(|c| c == '1').collect::<Vec<_>>();
        assert_eq!(stuff_bits(bits("0000")), 0);
        assert_eq!(stuff_bits(bits("00000")), 1);
        // After 00000 a stuff 1 goes in: 1111 then makes five ones.
        assert_eq!(stuff_bits(bits("000001111")), 2);
        assert_eq!(stuff_bits(bits("0000011110")), 2);
        assert_eq!(stuff_bits(bits("0101010101")), 0);
        assert_eq!(stuff_bits(bits(&"0".repeat(20))), 4);
    }

    #[test]
    fn frame_lengths() {
        let id = CanId::new(0x7FF).unwrap();
        assert!(CanId::new(0x800).is_err());
        assert!(Frame::data(id, &[0; 9]).is_err());
        assert!(Frame::remote(id, 9).is_err());
        let f = Frame::data(CanId::new(0x155).unwrap(), &[0x55; 8]).unwrap();
        assert_eq!(f.bits(), 47 + 64 + f.stuff_bits());
        assert!(f.bits() <= worst_case_bits(8));
        let r = Frame::remote(CanId::new(0x100).unwrap(), 8).unwrap();
        assert_eq!(r.payload(), &[] as &[u8]);
        assert_eq!(r.bits(), 47 + r.stuff_bits());
    }
}
