//! Bit fields inside big-endian quadlets, each defined exactly once with its
//! getter and setter side by side.
//!
//! A [`Field`] names a quadlet index and a bit range. Callers check the buffer
//! length once (the `check_len` of each view); after that `get`/`set` never
//! panic: an out-of-range quadlet reads as 0 and ignores writes, which a
//! checked view can never reach.

/// A bit range `hi..=lo` inside quadlet `q` of a big-endian buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Field {
    q: usize,
    shift: u32,
    mask: u32,
}

impl Field {
    /// Bits `hi` down to `lo` (inclusive) of quadlet `q`.
    pub const fn new(q: usize, hi: u32, lo: u32) -> Self {
        assert!(hi >= lo && hi < 32, "bit range out of a quadlet");
        let width = hi - lo + 1;
        let mask = if width == 32 {
            u32::MAX
        } else {
            (1u32 << width) - 1
        };
        Field { q, shift: lo, mask }
    }

    /// A whole quadlet.
    pub const fn quadlet(q: usize) -> Self {
        Self::new(q, 31, 0)
    }

    /// The largest value the field holds.
    pub const fn max(&self) -> u32 {
        self.mask
    }

    /// Extract the field from a quadlet value.
    #[inline]
    pub const fn extract(&self, quadlet: u32) -> u32 {
        (quadlet >> self.shift) & self.mask
    }

    /// Insert `value` (truncated to the field width) into a quadlet value.
    #[inline]
    pub const fn insert(&self, quadlet: u32, value: u32) -> u32 {
        (quadlet & !(self.mask << self.shift)) | ((value & self.mask) << self.shift)
    }

    /// Read the field from a byte buffer.
    #[inline]
    pub fn get(&self, buf: &[u8]) -> u32 {
        self.extract(read_quadlet(buf, self.q))
    }

    /// Write the field into a byte buffer.
    #[inline]
    pub fn set(&self, buf: &mut [u8], value: u32) {
        let q = read_quadlet(buf, self.q);
        write_quadlet(buf, self.q, self.insert(q, value));
    }
}

/// Read big-endian quadlet `q` of `buf`; 0 if it is not there.
#[inline]
pub fn read_quadlet(buf: &[u8], q: usize) -> u32 {
    let start = q.saturating_mul(4);
    match buf.get(start..start.saturating_add(4)) {
        Some(&[a, b, c, d]) => u32::from_be_bytes([a, b, c, d]),
        _ => 0,
    }
}

/// Write big-endian quadlet `q` of `buf`; ignored if it is not there.
#[inline]
pub fn write_quadlet(buf: &mut [u8], q: usize, value: u32) {
    let start = q.saturating_mul(4);
    if let Some(dst) = buf.get_mut(start..start.saturating_add(4)) {
        dst.copy_from_slice(&value.to_be_bytes());
    }
}

/// The big-endian quadlets of a byte block, in order (a trailing partial
/// quadlet is dropped).
pub fn quadlets(bytes: &[u8]) -> impl Iterator<Item = u32> + '_ {
    bytes.chunks_exact(4).map(|c| match *c {
        [a, b, c, d] => u32::from_be_bytes([a, b, c, d]),
        _ => 0, // chunks_exact(4) gives 4-byte chunks only
    })
}

/// Round a byte count up to whole quadlets.
pub const fn pad4(len: usize) -> usize {
    (len + 3) & !3
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn get_set_round_trip_and_isolation() {
        let f = Field::new(1, 15, 10);
        let mut buf = [0xA5u8; 8];
        f.set(&mut buf, 0x2A);
        assert_eq!(f.get(&buf), 0x2A);
        // Bits outside the field are untouched.
        assert_eq!(read_quadlet(&buf, 1) & !0xFC00, 0xA5A5_A5A5 & !0xFC00);
        assert_eq!(read_quadlet(&buf, 0), 0xA5A5_A5A5);
    }

    #[test]
    fn out_of_range_is_inert() {
        let f = Field::quadlet(3);
        let mut buf = [0u8; 4];
        f.set(&mut buf, 7);
        assert_eq!(buf, [0; 4]);
        assert_eq!(f.get(&buf), 0);
    }
}
