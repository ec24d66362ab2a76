//! Virtual time as the boards see it: picoseconds since the simulation
//! started, and the FPGA's 49.152 MHz system clock derived from it.
//!
//! Nothing in this crate reads a clock: every entry point takes `now`. The
//! representation (an integer count of picoseconds) is the one the simulated
//! bus uses, so converting between the two is free.

use core::ops::{Add, AddAssign, Sub};

/// Picoseconds per second.
pub const PS_PER_SECOND: u64 = 1_000_000_000_000;

/// The FPGA system clock (the 1394 PHY clock), 49.152 MHz (`ieee1394.md`,
/// "Link-PHY interface"; `fpga-board.md` section 4).
pub const SYSCLK_HZ: u64 = 49_152_000;

/// One watchdog tick: 256 system clocks, about 5.208 us (`fpga-board.md`
/// section 2, register 3).
pub const WATCHDOG_TICK_CLOCKS: u64 = 256;

/// A point in virtual time, in picoseconds since the simulation started.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Time(pub u64);

/// A span of virtual time, in picoseconds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct TimeDelta(pub u64);

impl Time {
    /// The start of the simulation.
    pub const ZERO: Time = Time(0);

    /// `us` microseconds after the start.
    pub const fn from_micros(us: u64) -> Time {
        Time(us.saturating_mul(1_000_000))
    }

    /// `ms` milliseconds after the start.
    pub const fn from_millis(ms: u64) -> Time {
        Time(ms.saturating_mul(1_000_000_000))
    }

    /// Seconds since the start, as a float (for the physics only).
    pub fn as_secs_f64(self) -> f64 {
        self.0 as f64 / PS_PER_SECOND as f64
    }

    /// Microseconds since the start, as a float.
    pub fn as_micros_f64(self) -> f64 {
        self.0 as f64 / 1_000_000.0
    }

    /// The value of a free-running 49.152 MHz counter started at time zero.
    pub const fn clocks(self) -> u64 {
        ((self.0 as u128 * SYSCLK_HZ as u128) / PS_PER_SECOND as u128) as u64
    }

    /// The earliest time at which the 49.152 MHz counter reads `clocks`.
    pub const fn from_clocks(clocks: u64) -> Time {
        let ps = (clocks as u128 * PS_PER_SECOND as u128).div_ceil(SYSCLK_HZ as u128);
        Time(if ps > u64::MAX as u128 {
            u64::MAX
        } else {
            ps as u64
        })
    }

    /// The span from `earlier` to `self`, zero if `earlier` is later.
    pub const fn saturating_since(self, earlier: Time) -> TimeDelta {
        TimeDelta(self.0.saturating_sub(earlier.0))
    }

    /// System clocks elapsed from `earlier` to `self` (counter difference),
    /// zero if `earlier` is later.
    pub const fn clocks_since(self, earlier: Time) -> u64 {
        self.clocks().saturating_sub(earlier.clocks())
    }
}

impl TimeDelta {
    /// No time.
    pub const ZERO: TimeDelta = TimeDelta(0);

    /// `ns` nanoseconds.
    pub const fn from_nanos(ns: u64) -> TimeDelta {
        TimeDelta(ns.saturating_mul(1_000))
    }

    /// `us` microseconds.
    pub const fn from_micros(us: u64) -> TimeDelta {
        TimeDelta(us.saturating_mul(1_000_000))
    }

    /// `ms` milliseconds.
    pub const fn from_millis(ms: u64) -> TimeDelta {
        TimeDelta(ms.saturating_mul(1_000_000_000))
    }

    /// `n` cycles of the 49.152 MHz system clock (rounded to the picosecond).
    pub const fn from_clocks(n: u64) -> TimeDelta {
        let ps = (n as u128 * PS_PER_SECOND as u128 + SYSCLK_HZ as u128 / 2) / SYSCLK_HZ as u128;
        TimeDelta(if ps > u64::MAX as u128 {
            u64::MAX
        } else {
            ps as u64
        })
    }

    /// Seconds, as a float (for the physics only).
    pub fn as_secs_f64(self) -> f64 {
        self.0 as f64 / PS_PER_SECOND as f64
    }

    /// Microseconds, as a float.
    pub fn as_micros_f64(self) -> f64 {
        self.0 as f64 / 1_000_000.0
    }
}

impl Add<TimeDelta> for Time {
    type Output = Time;
    fn add(self, rhs: TimeDelta) -> Time {
        Time(self.0.saturating_add(rhs.0))
    }
}

impl AddAssign<TimeDelta> for Time {
    fn add_assign(&mut self, rhs: TimeDelta) {
        *self = *self + rhs;
    }
}

impl Sub<Time> for Time {
    type Output = TimeDelta;
    /// Saturating: an earlier minus a later time is zero.
    fn sub(self, rhs: Time) -> TimeDelta {
        self.saturating_since(rhs)
    }
}

impl Add for TimeDelta {
    type Output = TimeDelta;
    fn add(self, rhs: TimeDelta) -> TimeDelta {
        TimeDelta(self.0.saturating_add(rhs.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clock_conversions() {
        // One second is exactly 49_152_000 clocks.
        assert_eq!(Time(PS_PER_SECOND).clocks(), SYSCLK_HZ);
        // 256 clocks are about 5.208 us.
        let tick = TimeDelta::from_clocks(WATCHDOG_TICK_CLOCKS);
        assert!((tick.as_micros_f64() - 5.208_333).abs() < 1e-3);
        // from_clocks is the first instant the counter shows that value.
        for n in [0u64, 1, 2, 3, 1000, 49_151_999, 123_456_789] {
            let t = Time::from_clocks(n);
            assert_eq!(t.clocks(), n);
            if t.0 > 0 {
                assert_eq!(Time(t.0 - 1).clocks(), n - 1);
            }
        }
        assert_eq!(
            Time::from_micros(10).clocks_since(Time::from_micros(5)),
            Time::from_micros(10).clocks() - Time::from_micros(5).clocks()
        );
        assert_eq!(Time::from_micros(1) - Time::from_micros(2), TimeDelta::ZERO);
    }
}
