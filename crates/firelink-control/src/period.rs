//! The servo period: one type from the configuration and the command line
//! to the runner.
//!
//! A [`ServoPeriod`] is a [`Duration`] (what pacing waits out) with the
//! rate derived from it ([`ServoPeriod::rate_hz`]). It is written either
//! way: `1ms`, `250us`, `0.5 s` or `1kHz`, `6000 Hz`
//! ([`FromStr`]), and shown the way that reads back to the same value
//! ([`fmt::Display`]).
//!
//! Rules:
//! - Every period lies in [`ServoPeriod::MIN`] (10 us, 100 kHz) to
//!   [`ServoPeriod::MAX`] (1 s, 1 Hz); construction is checked and says
//!   what was wrong ([`ServoPeriodError`]); no input panics.
//! - A period given as a rate keeps that rate exactly: 6000 Hz is a
//!   period of 166 667 ns on the nanosecond grid, but its `rate_hz()` is
//!   6000, not 5999.988, and the control law's period in seconds
//!   ([`ServoPeriod::as_secs_f64`]) is `1 / 6000`. So a rate written
//!   today runs and reports exactly as the rate-only settings did.
//! - A period given as a duration has `rate_hz() = 1 / period`.

use std::fmt;
use std::str::FromStr;
use std::time::Duration;

/// A checked servo period (see the [module docs](self)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ServoPeriod {
    /// The period on the nanosecond grid (pacing).
    duration: Duration,
    /// The rate, Hz: as given, or `1 / duration`.
    rate_hz: f64,
}

/// Why a servo period was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ServoPeriodError {
    /// The text is not a period or a rate.
    #[error(
        "servo period {text:?}: {why}; write a period or a rate with its unit, \
         e.g. 1ms, 250us or 1kHz"
    )]
    Malformed {
        /// The text, cut to 40 characters.
        text: String,
        /// What was wrong with it.
        why: &'static str,
    },
    /// A value outside 10 us to 1 s (100 kHz to 1 Hz).
    #[error("servo period {shown}: out of range, 10 us to 1 s (100 kHz to 1 Hz)")]
    OutOfRange {
        /// The value as given, with its unit.
        shown: String,
    },
}

impl ServoPeriod {
    /// The shortest period: 10 us (100 kHz).
    pub const MIN: Duration = Duration::from_micros(10);
    /// The longest period: 1 s (1 Hz).
    pub const MAX: Duration = Duration::from_secs(1);
    /// 1 ms, 1 kHz (the runner's default, the dVRK console's rate).
    pub const KHZ_1: ServoPeriod = ServoPeriod {
        duration: Duration::from_millis(1),
        rate_hz: 1000.0,
    };

    /// A period of `duration`.
    ///
    /// # Errors
    /// [`ServoPeriodError::OutOfRange`] outside [`MIN`](Self::MIN) to
    /// [`MAX`](Self::MAX).
    pub fn from_duration(duration: Duration) -> Result<ServoPeriod, ServoPeriodError> {
        if !(Self::MIN..=Self::MAX).contains(&duration) {
            return Err(ServoPeriodError::OutOfRange {
                shown: show_duration(duration),
            });
        }
        Ok(ServoPeriod {
            duration,
            rate_hz: 1.0 / duration.as_secs_f64(),
        })
    }

    /// The period of a rate in Hz, the rate kept exactly.
    ///
    /// # Errors
    /// [`ServoPeriodError::OutOfRange`] outside 1 Hz to 100 kHz (also for
    /// NaN and infinities).
    pub fn from_rate_hz(rate_hz: f64) -> Result<ServoPeriod, ServoPeriodError> {
        if !(1.0..=100_000.0).contains(&rate_hz) {
            return Err(ServoPeriodError::OutOfRange {
                shown: format!("{rate_hz} Hz"),
            });
        }
        Ok(ServoPeriod {
            duration: Duration::from_secs_f64(1.0 / rate_hz),
            rate_hz,
        })
    }

    /// The period in microseconds (e.g. MAHRU's `--period-us`).
    ///
    /// # Errors
    /// [`ServoPeriodError::OutOfRange`] outside 10 us to 1 s (also for NaN
    /// and infinities).
    pub fn from_micros_f64(us: f64) -> Result<ServoPeriod, ServoPeriodError> {
        if !(10.0..=1e6).contains(&us) {
            return Err(ServoPeriodError::OutOfRange {
                shown: format!("{us} us"),
            });
        }
        Self::from_duration(Duration::from_nanos((us * 1e3).round() as u64))
    }

    /// The period in seconds (e.g. Python's `period=0.001`).
    ///
    /// # Errors
    /// [`ServoPeriodError::OutOfRange`] outside 10 us to 1 s (also for NaN
    /// and infinities).
    pub fn from_secs_f64(secs: f64) -> Result<ServoPeriod, ServoPeriodError> {
        if !(1e-5..=1.0).contains(&secs) {
            return Err(ServoPeriodError::OutOfRange {
                shown: format!("{secs} s"),
            });
        }
        Self::from_duration(Duration::from_nanos((secs * 1e9).round() as u64))
    }

    /// The period on the nanosecond grid: what pacing waits out.
    pub fn as_duration(self) -> Duration {
        self.duration
    }

    /// The rate, Hz.
    pub fn rate_hz(self) -> f64 {
        self.rate_hz
    }

    /// The period in seconds as the control law sees it: `1 / rate_hz()`.
    pub fn as_secs_f64(self) -> f64 {
        1.0 / self.rate_hz
    }

    /// The period in microseconds, `1e6 / rate_hz()`.
    pub fn as_micros_f64(self) -> f64 {
        1e6 / self.rate_hz
    }

    /// Whether the period reads back from its duration (else it is shown
    /// as its rate).
    fn is_whole_duration(self) -> bool {
        self.rate_hz == 1.0 / self.duration.as_secs_f64()
    }
}

/// A duration in the largest unit that holds it exactly.
fn show_duration(d: Duration) -> String {
    let ns = d.as_nanos();
    for (unit, scale) in [("s", 1_000_000_000), ("ms", 1_000_000), ("us", 1_000)] {
        if ns % scale == 0 {
            return format!("{} {unit}", ns / scale);
        }
    }
    format!("{ns} ns")
}

impl fmt::Display for ServoPeriod {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.is_whole_duration() {
            f.write_str(&show_duration(self.duration))
        } else {
            write!(f, "{} Hz", self.rate_hz)
        }
    }
}

impl FromStr for ServoPeriod {
    type Err = ServoPeriodError;

    /// `<number><unit>`, a space allowed between: units `s`, `ms`, `us`
    /// (or `µs`), `ns` for a period, `Hz`, `kHz` for a rate (case as
    /// written here).
    fn from_str(text: &str) -> Result<ServoPeriod, ServoPeriodError> {
        let malformed = |why| ServoPeriodError::Malformed {
            text: text.chars().take(40).collect(),
            why,
        };
        let t = text.trim();
        let split = t
            .find(|c: char| !(c.is_ascii_digit() || matches!(c, '.' | 'e' | 'E' | '+' | '-')))
            .ok_or_else(|| malformed("no unit"))?;
        let (number, unit) = t.split_at(split);
        if number.is_empty() {
            return Err(malformed("no number"));
        }
        let value: f64 = number.parse().map_err(|_| malformed("not a number"))?;
        let shown = || format!("{} {}", number, unit.trim());
        let out_of_range = || ServoPeriodError::OutOfRange { shown: shown() };
        // The value in nanoseconds per unit, or in hertz per unit.
        let (scale, is_rate) = match unit.trim_start() {
            "s" => (1e9, false),
            "ms" => (1e6, false),
            "us" | "µs" => (1e3, false),
            "ns" => (1.0, false),
            "Hz" => (1.0, true),
            "kHz" => (1e3, true),
            _ => return Err(malformed("unknown unit (s, ms, us, ns, Hz or kHz)")),
        };
        if is_rate {
            return Self::from_rate_hz(value * scale).map_err(|_| out_of_range());
        }
        let ns = value * scale;
        if !(1e4..=1e9).contains(&ns) {
            return Err(out_of_range());
        }
        Self::from_duration(Duration::from_nanos(ns.round() as u64)).map_err(|_| out_of_range())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn parse(s: &str) -> Result<ServoPeriod, ServoPeriodError> {
        s.parse()
    }

    #[test]
    fn units_mean_what_they_say() {
        let ms = Duration::from_millis(1);
        for text in ["1ms", "1 ms", "1000us", "1000µs", "0.001s", "1e6ns"] {
            let p = parse(text).unwrap();
            assert_eq!(p.as_duration(), ms, "{text}");
            assert_eq!(p.rate_hz(), 1000.0, "{text}");
        }
        for text in ["1kHz", "1000Hz", "1000 Hz", "1 kHz"] {
            let p = parse(text).unwrap();
            assert_eq!(p.as_duration(), ms, "{text}");
            assert_eq!(p.to_string(), "1 ms", "{text}");
        }
        assert_eq!(parse("250us").unwrap().rate_hz(), 4000.0);
        assert_eq!(parse("1.5 ms").unwrap().to_string(), "1500 us");
    }

    #[test]
    fn the_constant_is_what_parsing_gives() {
        assert_eq!(parse("1kHz").unwrap(), ServoPeriod::KHZ_1);
        assert_eq!(
            ServoPeriod::from_rate_hz(1000.0).unwrap(),
            ServoPeriod::KHZ_1
        );
    }

    #[test]
    fn a_rate_is_kept_exactly() {
        let p = ServoPeriod::from_rate_hz(6000.0).unwrap();
        assert_eq!(p.rate_hz(), 6000.0);
        assert_eq!(p.as_secs_f64(), 1.0 / 6000.0);
        assert_eq!(p.as_duration(), Duration::from_secs_f64(1.0 / 6000.0));
        assert_eq!(p.to_string(), "6000 Hz");
        assert_eq!(parse("6kHz").unwrap(), p);
    }

    #[test]
    fn bounds_are_10_us_to_1_s() {
        assert!(parse("10us").is_ok());
        assert!(parse("1s").is_ok());
        assert!(parse("100kHz").is_ok());
        assert!(parse("1Hz").is_ok());
        for text in [
            "9999ns",
            "1.000001s",
            "100.001kHz",
            "0.99Hz",
            "0ms",
            "-1ms",
            "1e300s",
        ] {
            let e = parse(text).unwrap_err();
            assert!(
                matches!(e, ServoPeriodError::OutOfRange { .. }),
                "{text}: {e}"
            );
            assert!(e.to_string().contains("out of range"), "{e}");
        }
        for rate in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e300] {
            assert!(ServoPeriod::from_rate_hz(rate).is_err(), "{rate}");
        }
        for us in [0.0, 9.99, f64::NAN, f64::NEG_INFINITY, 1e300] {
            assert!(ServoPeriod::from_micros_f64(us).is_err(), "{us}");
        }
        for secs in [0.0, 9.99e-6, 1.000001, f64::NAN, f64::INFINITY, -1e-3] {
            let e = ServoPeriod::from_secs_f64(secs).unwrap_err();
            assert!(e.to_string().contains("out of range"), "{secs}: {e}");
        }
        assert_eq!(
            ServoPeriod::from_secs_f64(0.001).unwrap(),
            ServoPeriod::KHZ_1
        );
        assert_eq!(
            ServoPeriod::from_secs_f64(250e-6).unwrap().as_duration(),
            Duration::from_micros(250)
        );
        assert_eq!(
            ServoPeriod::from_micros_f64(2000.0).unwrap().as_duration(),
            Duration::from_millis(2)
        );
        assert!(ServoPeriod::from_duration(Duration::from_nanos(9_999)).is_err());
        assert!(ServoPeriod::from_duration(Duration::from_secs(2)).is_err());
    }

    #[test]
    fn bad_text_is_refused_with_a_clear_message() {
        for (text, why) in [
            ("", "no unit"),
            ("1000", "no unit"),
            ("ms", "no number"),
            ("1.2.3ms", "not a number"),
            ("1 fortnight", "unknown unit"),
            ("1 MHz", "unknown unit"),
        ] {
            let e = parse(text).unwrap_err().to_string();
            assert!(e.contains(why), "{text:?}: {e}");
            assert!(e.contains("e.g. 1ms, 250us or 1kHz"), "{e}");
        }
    }

    fn period() -> impl Strategy<Value = ServoPeriod> {
        prop_oneof![
            (10_000u64..=1_000_000_000)
                .prop_map(|ns| ServoPeriod::from_duration(Duration::from_nanos(ns)).unwrap()),
            (1.0f64..=100_000.0).prop_map(|hz| ServoPeriod::from_rate_hz(hz).unwrap()),
            (1u64..=100_000).prop_map(|hz| ServoPeriod::from_rate_hz(hz as f64).unwrap()),
        ]
    }

    proptest! {
        #[test]
        fn display_reads_back_to_the_same_period(p in period()) {
            let back: ServoPeriod = p.to_string().parse().unwrap();
            prop_assert_eq!(back, p);
            prop_assert!((ServoPeriod::MIN..=ServoPeriod::MAX).contains(&p.as_duration()));
        }

        #[test]
        fn any_text_parses_or_says_why(text in "\\PC{0,16}|[ 0-9eE.+-]{0,10}(s|ms|us|ns|Hz|kHz)?") {
            match text.parse::<ServoPeriod>() {
                Ok(p) => prop_assert!((ServoPeriod::MIN..=ServoPeriod::MAX).contains(&p.as_duration())),
                Err(e) => prop_assert!(!e.to_string().is_empty()),
            }
        }
    }
}
