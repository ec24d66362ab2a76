//! Virtual time: picosecond instants and durations.
//!
//! The bus never reads a clock. Every instant is a [`SimTime`] (picoseconds
//! since the simulation started) and every span a [`SimDuration`]
//! (picoseconds). One picosecond resolves a bit at S400 (2543 ps) exactly
//! enough that rounding never accumulates over a cycle, and `u64` picoseconds
//! last 213 days of virtual time.
//!
//! Arithmetic saturates instead of wrapping or panicking, so odd inputs (a
//! node asking for a timer in the past, a huge delay) stay well defined.
//!
//! The 49.152 MHz clock of every 1394 PHY, which the boards' FPGAs run on
//! ([`SYSTEM_CLOCK_HZ`]), is counted from the same time:
//! [`SimTime::clocks`], [`SimTime::from_clocks`], [`SimDuration::from_clocks`].
//! The emulated boards (`firelink-board`) use these types.

use core::fmt;
use core::ops::{Add, AddAssign, Mul, Sub};

pub use firelink_wire::phy::SYSTEM_CLOCK_HZ;

/// [`SYSTEM_CLOCK_HZ`] for arithmetic.
const CLOCK_HZ: u128 = SYSTEM_CLOCK_HZ as u128;

/// One clock is `PS_PER_CLOCK_NUM / PS_PER_CLOCK_DEN` ps (10^12 / 49.152e6
/// reduced: 125e6 / 6144, 20345.05 ps).
const PS_PER_CLOCK_NUM: u64 = 125_000_000;
const PS_PER_CLOCK_DEN: u64 = 6_144;

/// Whole clocks in `ps` picoseconds (rounded down): 64-bit arithmetic
/// while it cannot overflow (the first 50 minutes), else 128-bit; the same
/// result either way.
const fn ps_to_clocks(ps: u64) -> u64 {
    if ps <= u64::MAX / PS_PER_CLOCK_DEN {
        ps * PS_PER_CLOCK_DEN / PS_PER_CLOCK_NUM
    } else {
        ((ps as u128 * CLOCK_HZ) / PS_PER_S as u128) as u64
    }
}

/// Picoseconds in one nanosecond.
pub const PS_PER_NS: u64 = 1_000;
/// Picoseconds in one microsecond.
pub const PS_PER_US: u64 = 1_000_000;
/// Picoseconds in one second.
pub const PS_PER_S: u64 = 1_000_000_000_000;

/// Virtual time: picoseconds since the simulation started.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct SimTime(pub u64);

/// A span of virtual time in picoseconds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct SimDuration(pub u64);

impl SimTime {
    /// The start of the simulation.
    pub const ZERO: SimTime = SimTime(0);
    /// The last representable instant (used as "never").
    pub const MAX: SimTime = SimTime(u64::MAX);

    /// Microseconds since the start, as a float (for reports).
    pub fn as_micros_f64(self) -> f64 {
        self.0 as f64 / PS_PER_US as f64
    }

    /// Nanoseconds since the start (truncated).
    pub const fn as_nanos(self) -> u64 {
        self.0 / PS_PER_NS
    }

    /// The instant `us` microseconds after the start.
    pub fn from_micros_f64(us: f64) -> SimTime {
        SimTime(SimDuration::from_micros_f64(us).0)
    }

    /// The span since `earlier`, zero if `earlier` is later.
    pub const fn saturating_since(self, earlier: SimTime) -> SimDuration {
        SimDuration(self.0.saturating_sub(earlier.0))
    }

    /// `us` whole microseconds after the start.
    pub const fn from_micros(us: u64) -> SimTime {
        SimTime(us.saturating_mul(PS_PER_US))
    }

    /// `ms` whole milliseconds after the start.
    pub const fn from_millis(ms: u64) -> SimTime {
        SimTime(ms.saturating_mul(PS_PER_US * 1_000))
    }

    /// Seconds since the start, as a float (for physics and reports).
    pub fn as_secs_f64(self) -> f64 {
        self.0 as f64 / PS_PER_S as f64
    }

    /// The value of a free-running [`SYSTEM_CLOCK_HZ`] counter started at
    /// time zero.
    pub const fn clocks(self) -> u64 {
        ps_to_clocks(self.0)
    }

    /// The earliest instant at which that counter reads `clocks`.
    pub const fn from_clocks(clocks: u64) -> SimTime {
        // ps = clocks x 10^12 / 49.152 MHz = clocks x 125e6 / 6144 exactly;
        // in 64 bits for the first hour of virtual time.
        if clocks <= u64::MAX / PS_PER_CLOCK_NUM {
            return SimTime((clocks * PS_PER_CLOCK_NUM).div_ceil(PS_PER_CLOCK_DEN));
        }
        let ps = (clocks as u128 * PS_PER_S as u128).div_ceil(CLOCK_HZ);
        SimTime(if ps > u64::MAX as u128 {
            u64::MAX
        } else {
            ps as u64
        })
    }

    /// Clocks counted from `earlier` to `self` (the counter difference),
    /// zero if `earlier` is later.
    pub const fn clocks_since(self, earlier: SimTime) -> u64 {
        self.clocks().saturating_sub(earlier.clocks())
    }
}

impl SimDuration {
    /// No time at all.
    pub const ZERO: SimDuration = SimDuration(0);
    /// The longest representable span.
    pub const MAX: SimDuration = SimDuration(u64::MAX);

    /// `ps` picoseconds.
    pub const fn from_picos(ps: u64) -> SimDuration {
        SimDuration(ps)
    }

    /// `ns` nanoseconds.
    pub const fn from_nanos(ns: u64) -> SimDuration {
        SimDuration(ns.saturating_mul(PS_PER_NS))
    }

    /// `us` whole microseconds.
    pub const fn from_micros(us: u64) -> SimDuration {
        SimDuration(us.saturating_mul(PS_PER_US))
    }

    /// `ms` whole milliseconds.
    pub const fn from_millis(ms: u64) -> SimDuration {
        SimDuration(ms.saturating_mul(PS_PER_US * 1_000))
    }

    /// `us` microseconds given as a float, rounded to the nearest picosecond.
    /// Negative and NaN inputs give zero; huge ones saturate.
    pub fn from_micros_f64(us: f64) -> SimDuration {
        let ps = us * PS_PER_US as f64;
        if ps.is_nan() || ps <= 0.0 {
            SimDuration::ZERO
        } else if ps >= u64::MAX as f64 {
            SimDuration::MAX
        } else {
            SimDuration(ps.round() as u64)
        }
    }

    /// The span in microseconds, as a float.
    pub fn as_micros_f64(self) -> f64 {
        self.0 as f64 / PS_PER_US as f64
    }

    /// The span in nanoseconds (truncated).
    pub const fn as_nanos(self) -> u64 {
        self.0 / PS_PER_NS
    }

    /// `bits` bit times at `bits_per_second`, rounded to the nearest
    /// picosecond. A zero rate gives zero.
    pub fn from_bits(bits: u64, bits_per_second: u64) -> SimDuration {
        if bits_per_second == 0 {
            return SimDuration::ZERO;
        }
        let ps = (u128::from(bits) * u128::from(PS_PER_S) + u128::from(bits_per_second) / 2)
            / u128::from(bits_per_second);
        SimDuration(u64::try_from(ps).unwrap_or(u64::MAX))
    }

    /// `n` cycles of the [`SYSTEM_CLOCK_HZ`] clock, rounded to the nearest
    /// picosecond.
    pub const fn from_clocks(n: u64) -> SimDuration {
        if n <= u64::MAX / PS_PER_CLOCK_NUM {
            return SimDuration((n * PS_PER_CLOCK_NUM + PS_PER_CLOCK_DEN / 2) / PS_PER_CLOCK_DEN);
        }
        let ps = (n as u128 * PS_PER_S as u128 + CLOCK_HZ / 2) / CLOCK_HZ;
        SimDuration(if ps > u64::MAX as u128 {
            u64::MAX
        } else {
            ps as u64
        })
    }

    /// The span in seconds, as a float (for physics and reports).
    pub fn as_secs_f64(self) -> f64 {
        self.0 as f64 / PS_PER_S as f64
    }

    /// Whole cycles of the [`SYSTEM_CLOCK_HZ`] clock in the span.
    pub const fn as_clocks(self) -> u64 {
        ps_to_clocks(self.0)
    }

    /// The larger of two spans.
    pub fn max(self, other: SimDuration) -> SimDuration {
        if self >= other { self } else { other }
    }
}

impl Add<SimDuration> for SimTime {
    type Output = SimTime;
    fn add(self, rhs: SimDuration) -> SimTime {
        SimTime(self.0.saturating_add(rhs.0))
    }
}

impl AddAssign<SimDuration> for SimTime {
    fn add_assign(&mut self, rhs: SimDuration) {
        *self = *self + rhs;
    }
}

impl Sub<SimTime> for SimTime {
    type Output = SimDuration;
    /// Saturating: an earlier minus a later instant is zero.
    fn sub(self, rhs: SimTime) -> SimDuration {
        self.saturating_since(rhs)
    }
}

impl Sub<SimDuration> for SimTime {
    type Output = SimTime;
    fn sub(self, rhs: SimDuration) -> SimTime {
        SimTime(self.0.saturating_sub(rhs.0))
    }
}

impl Add for SimDuration {
    type Output = SimDuration;
    fn add(self, rhs: SimDuration) -> SimDuration {
        SimDuration(self.0.saturating_add(rhs.0))
    }
}

impl AddAssign for SimDuration {
    fn add_assign(&mut self, rhs: SimDuration) {
        *self = *self + rhs;
    }
}

impl Sub for SimDuration {
    type Output = SimDuration;
    fn sub(self, rhs: SimDuration) -> SimDuration {
        SimDuration(self.0.saturating_sub(rhs.0))
    }
}

impl Mul<u64> for SimDuration {
    type Output = SimDuration;
    fn mul(self, rhs: u64) -> SimDuration {
        SimDuration(self.0.saturating_mul(rhs))
    }
}

/// Serialized as integer picoseconds.
impl serde::Serialize for SimTime {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_u64(self.0)
    }
}

/// Serialized as integer picoseconds.
impl serde::Serialize for SimDuration {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_u64(self.0)
    }
}

impl fmt::Display for SimTime {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:.6}us", self.as_micros_f64())
    }
}

impl fmt::Display for SimDuration {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:.6}us", self.as_micros_f64())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conversions() {
        assert_eq!(SimDuration::from_micros(3).0, 3_000_000);
        assert_eq!(SimDuration::from_nanos(40).0, 40_000);
        assert_eq!(SimDuration::from_micros_f64(0.144).0, 144_000);
        assert_eq!(SimDuration::from_micros_f64(-1.0), SimDuration::ZERO);
        assert_eq!(SimDuration::from_micros_f64(f64::NAN), SimDuration::ZERO);
        assert_eq!(
            SimDuration::from_micros_f64(f64::INFINITY),
            SimDuration::MAX
        );
        let t = SimTime::ZERO + SimDuration::from_micros(5);
        assert_eq!(t.as_micros_f64(), 5.0);
        assert_eq!(t - SimTime(10), SimDuration(5_000_000 - 10));
        assert_eq!(SimTime(1) - t, SimDuration::ZERO);
        assert_eq!(SimTime::MAX + SimDuration(1), SimTime::MAX);
    }

    #[test]
    fn the_64_bit_conversions_agree_with_128_bit_arithmetic() {
        let slow_clocks = |ps: u64| ((ps as u128 * CLOCK_HZ) / PS_PER_S as u128) as u64;
        let slow_from = |c: u64| (c as u128 * PS_PER_S as u128).div_ceil(CLOCK_HZ) as u64;
        let slow_dur = |n: u64| ((n as u128 * PS_PER_S as u128 + CLOCK_HZ / 2) / CLOCK_HZ) as u64;
        let ps_edge = u64::MAX / PS_PER_CLOCK_DEN;
        let clock_edge = u64::MAX / PS_PER_CLOCK_NUM;
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        let mut values = vec![0, 1, 2, 20_345, 20_346, ps_edge - 1, ps_edge, ps_edge + 1];
        values.extend([clock_edge - 1, clock_edge, clock_edge + 1, u64::MAX / 2]);
        for _ in 0..10_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            values.push(x >> (x % 40));
        }
        for v in values {
            assert_eq!(SimTime(v).clocks(), slow_clocks(v), "{v} ps");
            assert_eq!(SimDuration(v).as_clocks(), slow_clocks(v), "{v} ps");
            if v <= u64::MAX / 1_000_000 {
                assert_eq!(SimTime::from_clocks(v).0, slow_from(v), "{v} clocks");
                assert_eq!(SimDuration::from_clocks(v).0, slow_dur(v), "{v} clocks");
            }
        }
    }

    #[test]
    fn clock_conversions() {
        // One second is exactly 49_152_000 clocks.
        assert_eq!(SimTime(PS_PER_S).clocks(), u64::from(SYSTEM_CLOCK_HZ));
        // 256 clocks (a watchdog tick) are about 5.208 us.
        let tick = SimDuration::from_clocks(256);
        assert!((tick.as_micros_f64() - 5.208_333).abs() < 1e-3);
        // from_clocks is the first instant the counter shows that value.
        for n in [0u64, 1, 2, 3, 1000, 49_151_999, 123_456_789] {
            let t = SimTime::from_clocks(n);
            assert_eq!(t.clocks(), n);
            if t.0 > 0 {
                assert_eq!(SimTime(t.0 - 1).clocks(), n - 1);
            }
        }
        assert_eq!(
            SimTime::from_micros(10).clocks_since(SimTime::from_micros(5)),
            SimTime::from_micros(10).clocks() - SimTime::from_micros(5).clocks()
        );
        assert_eq!(SimTime::from_millis(2).as_secs_f64(), 0.002);
    }

    #[test]
    fn bit_times() {
        // One quadlet at S400 is 81.4 ns (ieee1394.md).
        let q = SimDuration::from_bits(32, 393_216_000);
        assert_eq!(q.as_nanos(), 81);
        // One bit at the base rate: 10172.526 ps, rounded.
        assert_eq!(SimDuration::from_bits(1, 98_304_000).0, 10_173);
        assert_eq!(SimDuration::from_bits(1, 0), SimDuration::ZERO);
    }
}
