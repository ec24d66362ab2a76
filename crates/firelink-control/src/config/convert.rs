//! Unit conversions: raw board values <-> SI. The only place in Firelink
//! where units change.
//!
//! Rules that hold for every method here, whatever the configuration:
//! no panics; a function that returns raw bits never returns a value outside
//! the register's range, and maps a NaN input to the safe value it names
//! (zero current for the DAC). Functions returning SI values from bits only
//! return NaN when the configuration itself is invalid (a zero scale), which
//! [`IoConfig::validate`](super::IoConfig::validate) rules out.

use super::{DriveConfig, EncoderConfig, Limits, LinearFunction, PotentiometerConfig};

/// Rounds `x` to the nearest integer (halves away from zero, as
/// [`f64::round`]) in `[lo, hi]`, whole bounds within ±2^52; NaN gives
/// `nan_value()`.
///
/// Clamping to whole bounds and then rounding is rounding and then
/// clamping, and a clamped value rounds exactly through its truncation:
/// no call to the software `round` of the baseline x86-64 target (the
/// servo cycle converts every joint's current with it).
#[inline]
fn round_clamped(x: f64, lo: f64, hi: f64, nan_value: impl FnOnce() -> i64) -> i64 {
    if x.is_nan() {
        return nan_value();
    }
    // (`max` and `min` without their NaN cases.)
    let x = if x < lo {
        lo
    } else if x > hi {
        hi
    } else {
        x
    };
    // Exact: `x` and its truncation are both within ±2^52.
    let whole = x as i64;
    let fraction = x - whole as f64;
    if fraction >= 0.5 {
        whole + 1
    } else if fraction <= -0.5 {
        whole - 1
    } else {
        whole
    }
}

/// `x` limited to `[-limit, limit]`; a non-finite or negative `limit` counts
/// as 0, a NaN `x` as 0.
#[inline]
fn clamp_symmetric(x: f64, limit: f64) -> f64 {
    clamp_within(x, usable_limit(limit))
}

/// `limit` if it is finite and above 0, else 0.
#[inline]
fn usable_limit(limit: f64) -> f64 {
    // (False for NaN.)
    if limit > 0.0 && limit < f64::INFINITY {
        limit
    } else {
        0.0
    }
}

/// `x` limited to `[-l, l]` for a usable limit `l` ([`usable_limit`]), a
/// NaN `x` as 0.
#[inline]
fn clamp_within(x: f64, l: f64) -> f64 {
    // (`max` and `min` without their NaN cases.)
    if x.is_nan() {
        0.0
    } else if x < -l {
        -l
    } else if x > l {
        l
    } else {
        x
    }
}

impl LinearFunction {
    /// The identity.
    pub const IDENTITY: LinearFunction = LinearFunction {
        scale: 1.0,
        offset: 0.0,
    };

    /// `scale * x + offset`.
    #[inline]
    pub fn apply(&self, x: f64) -> f64 {
        self.scale * x + self.offset
    }

    /// The `x` with `apply(x) == y`: `(y - offset) / scale` (NaN if the
    /// scale is zero, which validation forbids).
    pub fn invert(&self, y: f64) -> f64 {
        if self.scale == 0.0 {
            f64::NAN
        } else {
            (y - self.offset) / self.scale
        }
    }
}

impl DriveConfig {
    /// DAC code of a current command (`fpga-board.md` §3, DAC register bits
    /// 15:0). The current is first limited to `±maximum_current`; NaN means
    /// 0 A. The result is always a valid 16-bit code.
    #[inline]
    pub fn current_to_bits(&self, amps: f64) -> u16 {
        self.current_to_bits_within(amps, self.current_limit())
    }

    /// What [`current_to_bits`](Self::current_to_bits) limits a current
    /// to: `maximum_current` when it is finite and above 0, else 0.
    #[inline]
    pub(crate) fn current_limit(&self) -> f64 {
        usable_limit(self.maximum_current)
    }

    /// [`current_to_bits`](Self::current_to_bits) with its
    /// [`current_limit`](Self::current_limit) worked out beforehand (the
    /// servo cycle keeps it per joint).
    #[inline]
    pub(crate) fn current_to_bits_within(&self, amps: f64, limit: f64) -> u16 {
        let a = clamp_within(amps, limit);
        let zero = || round_clamped(self.current_to_bits.offset, 0.0, 65535.0, || 32768);
        round_clamped(self.current_to_bits.apply(a), 0.0, 65535.0, zero) as u16
    }

    /// DAC code for zero current (the amplifier's neutral command).
    #[inline]
    pub fn zero_current_bits(&self) -> u16 {
        self.current_to_bits(0.0)
    }

    /// The current a DAC code commands (the inverse of
    /// [`current_to_bits`](Self::current_to_bits), for emulators).
    pub fn bits_to_commanded_current(&self, bits: u16) -> f64 {
        self.current_to_bits.invert(f64::from(bits))
    }

    /// Measured current from the ADC's current field (ADC register bits 15:0).
    pub fn bits_to_current(&self, bits: u16) -> f64 {
        self.bits_to_current.apply(f64::from(bits))
    }

    /// The ADC code an amplifier reports for `amps` (inverse of
    /// [`bits_to_current`](Self::bits_to_current), for emulators); saturates
    /// at the 16-bit range, NaN gives the code of 0 A.
    pub fn current_to_feedback_bits(&self, amps: f64) -> u16 {
        let zero = || round_clamped(self.bits_to_current.invert(0.0), 0.0, 65535.0, || 32768);
        round_clamped(self.bits_to_current.invert(amps), 0.0, 65535.0, zero) as u16
    }

    /// Motor current for a joint effort (N m or N).
    pub fn effort_to_current(&self, effort: f64) -> f64 {
        self.effort_to_current.apply(effort)
    }

    /// Joint effort for a motor current.
    pub fn current_to_effort(&self, amps: f64) -> f64 {
        self.effort_to_current.invert(amps)
    }

    /// `amps` limited to `±maximum_current` (NaN gives 0).
    pub fn limit_current(&self, amps: f64) -> f64 {
        clamp_symmetric(amps, self.maximum_current)
    }
}

impl EncoderConfig {
    /// The encoder count register is offset-binary around this value
    /// (`fpga-board.md` §3, ENC_POSITION bits 23:0; also the neutral preload).
    pub const MIDRANGE: u32 = 0x80_0000;
    /// Largest signed count the 24-bit register can hold.
    pub const MAX_COUNT: i32 = 0x7F_FFFF;
    /// Smallest signed count.
    pub const MIN_COUNT: i32 = -0x80_0000;

    /// Signed count from the ENC_POSITION register (bits 23:0; higher bits,
    /// overflow and the Rev 8 A/B/index bits, are ignored).
    pub fn counts_from_bits(bits: u32) -> i32 {
        (bits & 0xFF_FFFF) as i32 - Self::MIDRANGE as i32
    }

    /// The ENC_PRELOAD value for a signed count (saturating to 24 bits).
    pub fn bits_from_counts(counts: i32) -> u32 {
        let c = counts.clamp(Self::MIN_COUNT, Self::MAX_COUNT);
        (c + Self::MIDRANGE as i32) as u32
    }

    /// Joint position from the ENC_POSITION register.
    #[inline]
    pub fn bits_to_position(&self, bits: u32) -> f64 {
        self.counts_to_position(i64::from(Self::counts_from_bits(bits)))
    }

    /// Joint position of a signed count (any width: the host may unwrap
    /// overflows).
    #[inline]
    pub fn counts_to_position(&self, counts: i64) -> f64 {
        self.bits_to_position.apply(counts as f64)
    }

    /// Nearest signed count for a position, saturating to the 24-bit range;
    /// NaN gives 0.
    pub fn position_to_counts(&self, position: f64) -> i32 {
        let c = self.bits_to_position.invert(position);
        round_clamped(
            c,
            f64::from(Self::MIN_COUNT),
            f64::from(Self::MAX_COUNT),
            || 0,
        ) as i32
    }

    /// The ENC_PRELOAD register value that makes the encoder read `position`
    /// (NaN gives the neutral preload `0x800000`).
    pub fn position_to_preload_bits(&self, position: f64) -> u32 {
        Self::bits_from_counts(self.position_to_counts(position))
    }

    /// Joint velocity from a count rate (counts per second), e.g. a software
    /// difference of positions or the firmware's period measurement once the
    /// host has turned it into counts per second.
    pub fn counts_per_second_to_velocity(&self, counts_per_second: f64) -> f64 {
        self.bits_to_position.scale * counts_per_second
    }

    /// Position change of one count (the encoder's resolution, signed).
    pub fn position_per_count(&self) -> f64 {
        self.bits_to_position.scale
    }

    /// `position` kept inside the soft limits (NaN gives the limits' middle).
    pub fn clamp_to_soft_limits(&self, position: f64) -> f64 {
        self.position_limits_soft.clamp(position)
    }
}

impl Limits {
    /// Whether `lower <= x <= upper` (false for NaN).
    pub fn contains(&self, x: f64) -> bool {
        self.lower <= x && x <= self.upper
    }

    /// `x` kept inside the interval; NaN gives the middle. Never panics,
    /// even if the limits are invalid.
    pub fn clamp(&self, x: f64) -> f64 {
        if x.is_nan() {
            0.5 * (self.lower + self.upper)
        } else {
            x.max(self.lower).min(self.upper)
        }
    }

    /// `upper - lower`.
    pub fn span(&self) -> f64 {
        self.upper - self.lower
    }
}

impl PotentiometerConfig {
    /// Volts at the ADC from the potentiometer field (ADC register bits 31:16).
    #[inline]
    pub fn bits_to_voltage(&self, bits: u16) -> f64 {
        self.bits_to_voltage.apply(f64::from(bits))
    }

    /// Joint position for a pot voltage.
    #[inline]
    pub fn voltage_to_position(&self, volts: f64) -> f64 {
        self.voltage_to_position.apply(volts)
    }

    /// Joint position from the potentiometer field.
    #[inline]
    pub fn bits_to_position(&self, bits: u16) -> f64 {
        self.voltage_to_position(self.bits_to_voltage(bits))
    }

    /// The pot field that reads as `position` (for emulators); saturates at
    /// the 16-bit range, NaN gives 0.
    pub fn position_to_bits(&self, position: f64) -> u16 {
        let volts = self.voltage_to_position.invert(position);
        round_clamped(self.bits_to_voltage.invert(volts), 0.0, 65535.0, || 0) as u16
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What `round_clamped` computes without the shortcut.
    fn by_round(x: f64, lo: f64, hi: f64) -> f64 {
        x.round().max(lo).min(hi)
    }

    #[test]
    fn round_clamped_is_round_then_clamp() {
        let mut xs = vec![
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.5,
            2.5,
            -2.5,
            0.499_999_999_999_999_94,
            -0.499_999_999_999_999_94,
            32767.5,
            32768.49999,
            65534.5,
            65535.4,
            65535.5,
            -1e300,
            1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            4_503_599_627_370_495.5,
            -4_503_599_627_370_495.5,
            9.1e15,
            -8_388_608.5,
            8_388_607.5,
        ];
        // A sweep over both ranges in steps that hit halves and near-halves.
        xs.extend((-40_000..140_000).map(|k| f64::from(k) * 0.499_7));
        xs.extend((-20_000..20_000).map(|k| f64::from(k) * 0.25));
        let wide = 4_503_599_627_370_496.0;
        for (lo, hi) in [(0.0, 65535.0), (-8_388_608.0, 8_388_607.0), (-wide, wide)] {
            for &x in &xs {
                let got = round_clamped(x, lo, hi, || i64::MIN);
                let want = by_round(x, lo, hi);
                assert!(got as f64 == want, "{x} in [{lo}, {hi}]: {got} != {want}");
            }
            assert_eq!(round_clamped(f64::NAN, lo, hi, || 7), 7);
        }
    }

    fn qla_drive(direction: f64) -> DriveConfig {
        // The QLA1 factors: 16-bit DAC, +-6.25 A full scale (fpga-board.md §3).
        DriveConfig {
            current_to_bits: LinearFunction {
                scale: direction * 32768.0 / 6.25,
                offset: 32768.0,
            },
            bits_to_current: LinearFunction {
                scale: direction * 6.25 / 32768.0,
                offset: -direction * 6.25,
            },
            effort_to_current: LinearFunction {
                scale: 0.36,
                offset: 0.0,
            },
            maximum_current: 0.67,
        }
    }

    #[test]
    fn drive_matches_qla_formula() {
        let d = qla_drive(1.0);
        // amps = bits * 12.5 / 65536 - 6.25
        for bits in [0u16, 1, 0x7FFF, 0x8000, 0xC000, 0xFFFF] {
            let want = f64::from(bits) * 12.5 / 65536.0 - 6.25;
            assert!((d.bits_to_current(bits) - want).abs() < 1e-12);
        }
        assert_eq!(d.zero_current_bits(), 0x8000);
        assert_eq!(d.current_to_bits(0.5), 0x8000 + 2621);
        // Clamped to the maximum current, NaN is zero current.
        assert_eq!(d.current_to_bits(100.0), d.current_to_bits(0.67));
        assert_eq!(d.current_to_bits(f64::NAN), 0x8000);
        assert_eq!(
            d.current_to_bits(f64::NEG_INFINITY),
            d.current_to_bits(-0.67)
        );
        let inv = qla_drive(-1.0);
        assert_eq!(inv.current_to_bits(0.5), 0x8000 - 2621);
        assert!((inv.bits_to_current(inv.current_to_feedback_bits(0.3)) - 0.3).abs() < 2e-4);
        assert!((d.bits_to_commanded_current(d.current_to_bits(0.25)) - 0.25).abs() < 2e-4);
        assert!((d.current_to_effort(d.effort_to_current(0.1)) - 0.1).abs() < 1e-12);
    }

    #[test]
    fn encoder_offset_binary() {
        assert_eq!(EncoderConfig::counts_from_bits(0x80_0000), 0);
        assert_eq!(EncoderConfig::counts_from_bits(0x80_0001), 1);
        assert_eq!(EncoderConfig::counts_from_bits(0x7F_FFFF), -1);
        assert_eq!(
            EncoderConfig::counts_from_bits(0x0100_0000 | 5),
            5 - 0x80_0000
        );
        assert_eq!(EncoderConfig::bits_from_counts(-1), 0x7F_FFFF);
        assert_eq!(EncoderConfig::bits_from_counts(i32::MAX), 0xFF_FFFF);
        assert_eq!(EncoderConfig::bits_from_counts(i32::MIN), 0);
        let e = EncoderConfig {
            bits_to_position: LinearFunction {
                scale: -1e-4,
                offset: 0.0,
            },
            position_limits_soft: Limits {
                lower: -1.0,
                upper: 1.0,
            },
            velocity_source: None,
            counts_per_turn: Some(4000),
        };
        assert_eq!(e.position_to_counts(0.5), -5000);
        assert_eq!(e.position_to_preload_bits(0.5), 0x80_0000 - 5000);
        assert!((e.bits_to_position(0x80_0000 - 5000) - 0.5).abs() < 1e-12);
        assert_eq!(e.position_to_preload_bits(f64::NAN), 0x80_0000);
        assert_eq!(e.position_to_counts(1e12), EncoderConfig::MIN_COUNT);
        assert_eq!(e.clamp_to_soft_limits(3.0), 1.0);
        assert_eq!(e.clamp_to_soft_limits(f64::NAN), 0.0);
        assert!((e.counts_per_second_to_velocity(1000.0) + 0.1).abs() < 1e-12);
    }

    #[test]
    fn potentiometer_round_trip() {
        let p = PotentiometerConfig {
            bits_to_voltage: LinearFunction {
                scale: 4.5 / 65536.0,
                offset: 0.0,
            },
            voltage_to_position: LinearFunction {
                scale: 0.8,
                offset: -1.8,
            },
        };
        assert!((p.bits_to_voltage(65535) - 4.5 * 65535.0 / 65536.0).abs() < 1e-12);
        for pos in [-1.7, 0.0, 0.3, 1.7] {
            let bits = p.position_to_bits(pos);
            assert!((p.bits_to_position(bits) - pos).abs() < 1e-4, "{pos}");
        }
        assert_eq!(p.position_to_bits(100.0), 65535);
        assert_eq!(p.position_to_bits(-100.0), 0);
        assert_eq!(p.position_to_bits(f64::NAN), 0);
    }
}
