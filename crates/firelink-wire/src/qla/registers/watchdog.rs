//! WATCHDOG (`fpga-board.md` §2): the period register in ticks of 256 system
//! clocks and the host-side setting (off or a duration) with its range checks
//! and text form.

use super::*;

quadlet_register! {
    /// WATCHDOG: the period in ticks of 256 system clocks, 5.208 us
    /// (`fpga-board.md` §2, §7); 0 disables it.
    pub struct Watchdog {
        /// The period in ticks, bits 15:0.
        ticks, set_ticks, with_ticks: u16 = field::WATCHDOG_TICKS;
        /// Rev 8: which status the board's LED shows (the watchdog period
        /// when set), bit 31; stored and read back (BoardRegs.v).
        led_select, set_led_select, with_led_select: bool = field::WATCHDOG_LED;
    }
}

impl Watchdog {
    /// System clocks per watchdog tick.
    pub const CLOCKS_PER_TICK: u32 = 256;
    /// The watchdog is off.
    pub const DISABLED: Watchdog = Watchdog(0);
    /// The period after power-up: `0x1680` ticks = 30 ms (`fpga-board.md` §2).
    pub const POWER_UP: Watchdog = Watchdog(0x1680);

    /// Nanoseconds per tick are 256e9 / 49.152e6 = 15625 / 3 exactly.
    const TICK_NS_NUM: u128 = 15_625;
    const TICK_NS_DEN: u128 = 3;

    /// Whether the watchdog is off.
    pub fn is_disabled(self) -> bool {
        self.ticks() == 0
    }

    /// The period as a duration (zero when disabled), rounded down to
    /// whole nanoseconds.
    pub fn period(self) -> Duration {
        let ns = u128::from(self.ticks()) * Self::TICK_NS_NUM / Self::TICK_NS_DEN;
        Duration::from_nanos(ns as u64)
    }

    /// The watchdog word for `period`, rounded to the nearest tick; a
    /// nonzero period never rounds down to 0 (which would disable it).
    ///
    /// # Errors
    /// [`Error::FieldRange`] above 65535 ticks (about 341 ms).
    pub fn from_period(period: Duration) -> Result<Watchdog> {
        let ns = period.as_nanos();
        let ticks = (ns * Self::TICK_NS_DEN + Self::TICK_NS_NUM / 2) / Self::TICK_NS_NUM;
        let ticks = if ticks == 0 && ns > 0 { 1 } else { ticks };
        let max = field::WATCHDOG_TICKS.max();
        match u16::try_from(ticks) {
            Ok(t) => Ok(Watchdog::default().with_ticks(t)),
            Err(_) => Err(Error::FieldRange {
                field: "watchdog ticks",
                value: u64::try_from(ticks).unwrap_or(u64::MAX),
                max: u64::from(max),
            }),
        }
    }
}

/// A watchdog setting as a person asks for it: a period the WATCHDOG
/// register can hold (one tick, 5.208 us, to 65535 ticks, about 341 ms), or
/// off, which only the word `off` gives. Every front end (flags, web API,
/// configuration files, Python) goes through [`WatchdogSetting::parse`] or
/// [`WatchdogSetting::from_ms`]: a period too short for one tick used to
/// become register value 0, which turns the watchdog off without a word.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum WatchdogSetting {
    /// Off: a host that stops leaves the amplifiers on with the last
    /// command. Say so loudly ([`WatchdogSetting::OFF_WARNING`]).
    Off,
    /// This register word (never 0 ticks).
    Period(Watchdog),
}

/// A watchdog period that the register cannot hold (or is not a number).
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error(
    "watchdog period {} ms is out of range: {}, or `off`",
    crate::human::Number(*asked_ms),
    WatchdogSetting::RANGE
)]
pub struct WatchdogRangeError {
    /// What was asked for, ms.
    pub asked_ms: f64,
}

/// The text given for a watchdog is neither `off` nor a number.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum WatchdogParseError {
    /// Not `off` and not a number.
    #[error("a watchdog is a period in ms or `off`")]
    NotANumber,
    /// A number out of range.
    #[error(transparent)]
    Range(#[from] WatchdogRangeError),
}

impl WatchdogSetting {
    /// The shortest period, ms: one tick (256 / 49.152 MHz).
    pub const MIN_MS: f64 = 256.0 / 49_152.0;
    /// The longest period, ms: 65535 ticks.
    pub const MAX_MS: f64 = 65_535.0 * 256.0 / 49_152.0;
    /// The range in words, with bounds that are themselves accepted.
    pub const RANGE: &'static str =
        "from 0.00521 ms (one firmware tick of 5.208 us) to 341.32 ms (65535 ticks)";
    /// What to print when the watchdog is off.
    pub const OFF_WARNING: &'static str = "WARNING: board watchdogs are OFF: if this host \
        stops, the amplifiers stay enabled with the last command";

    /// A period in milliseconds, rounded to the nearest tick.
    ///
    /// # Errors
    /// Below one tick, above 65535 ticks, or not finite.
    pub fn from_ms(ms: f64) -> core::result::Result<WatchdogSetting, WatchdogRangeError> {
        let err = WatchdogRangeError { asked_ms: ms };
        // (False for NaN.)
        if !(Self::MIN_MS..=Self::MAX_MS).contains(&ms) {
            return Err(err);
        }
        let ticks = (ms / Self::MIN_MS).round();
        if !(1.0..=65_535.0).contains(&ticks) {
            return Err(err);
        }
        Ok(WatchdogSetting::Period(
            Watchdog::default().with_ticks(ticks as u16),
        ))
    }

    /// A period as a duration, rounded to the nearest tick.
    ///
    /// # Errors
    /// Below one tick (zero included: off is [`WatchdogSetting::Off`]),
    /// above 65535 ticks.
    pub fn from_period(
        period: Duration,
    ) -> core::result::Result<WatchdogSetting, WatchdogRangeError> {
        Self::from_ms(period.as_secs_f64() * 1e3)
    }

    /// `off` (any case) or a period in milliseconds.
    ///
    /// # Errors
    /// Not a number, or out of range.
    pub fn parse(text: &str) -> core::result::Result<WatchdogSetting, WatchdogParseError> {
        let t = text.trim();
        if t.eq_ignore_ascii_case("off") {
            return Ok(WatchdogSetting::Off);
        }
        let ms: f64 = t.parse().map_err(|_| WatchdogParseError::NotANumber)?;
        Ok(Self::from_ms(ms)?)
    }

    /// The register word to program (0 ticks only when off).
    pub fn register(self) -> Watchdog {
        match self {
            WatchdogSetting::Off => Watchdog::DISABLED,
            WatchdogSetting::Period(w) => w,
        }
    }

    /// The period, or `None` when off.
    pub fn period(self) -> Option<Duration> {
        match self {
            WatchdogSetting::Off => None,
            WatchdogSetting::Period(w) => Some(w.period()),
        }
    }

    /// The period, zero when off (for arithmetic on waits).
    pub fn period_or_zero(self) -> Duration {
        self.period().unwrap_or(Duration::ZERO)
    }

    /// Whether it is off.
    pub fn is_off(self) -> bool {
        self == WatchdogSetting::Off
    }

    /// The warning to print, or `None` when a period is set.
    pub fn warning(self) -> Option<&'static str> {
        self.is_off().then_some(Self::OFF_WARNING)
    }
}

impl Default for WatchdogSetting {
    /// 20 ms, the dVRK's and the demo's period.
    fn default() -> Self {
        WatchdogSetting::Period(Watchdog::default().with_ticks(3840))
    }
}

impl core::fmt::Display for WatchdogSetting {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            WatchdogSetting::Off => f.write_str("off"),
            WatchdogSetting::Period(w) => {
                let ms = w.period().as_secs_f64() * 1e3;
                write!(f, "{} ms", crate::human::Number((ms * 1e4).round() / 1e4))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn watchdog_settings_refuse_what_the_register_cannot_hold() {
        use std::string::ToString;
        // Under one tick used to become 0 ticks: the watchdog off.
        for ms in [
            1e-7,
            1e-9,
            0.0,
            -5.0,
            0.005,
            f64::NAN,
            f64::INFINITY,
            341.4,
            1e300,
        ] {
            let e = WatchdogSetting::from_ms(ms).unwrap_err();
            assert!(e.to_string().contains("out of range"), "{e}");
        }
        assert!(
            WatchdogSetting::from_ms(1e300)
                .unwrap_err()
                .to_string()
                .contains("1e300 ms")
        );
        assert!(WatchdogSetting::from_period(Duration::ZERO).is_err());
        assert!(WatchdogSetting::from_period(Duration::from_nanos(5000)).is_err());
        // The bounds the message shows are accepted.
        assert!(WatchdogSetting::from_ms(0.00521).is_ok());
        assert!(WatchdogSetting::from_ms(341.32).is_ok());
        let one = WatchdogSetting::from_ms(WatchdogSetting::MIN_MS).unwrap();
        assert_eq!(one.register().ticks(), 1);
        let max = WatchdogSetting::from_ms(WatchdogSetting::MAX_MS).unwrap();
        assert_eq!(max.register().ticks(), 0xFFFF);
        let twenty = WatchdogSetting::parse(" 20 ").unwrap();
        assert_eq!(twenty, WatchdogSetting::default());
        assert_eq!(twenty.to_string(), "20 ms");
        assert_eq!(twenty.register().ticks(), 3840);
        assert_eq!(WatchdogSetting::parse("OFF").unwrap(), WatchdogSetting::Off);
        assert!(WatchdogSetting::Off.warning().is_some());
        assert_eq!(WatchdogSetting::Off.register(), Watchdog::DISABLED);
        assert!(WatchdogSetting::parse("zero").is_err());
        assert!(WatchdogSetting::parse("0").is_err());
    }

    #[test]
    fn watchdog_ticks() {
        assert_eq!(Watchdog::POWER_UP.ticks(), 0x1680);
        assert_eq!(Watchdog::POWER_UP.period(), Duration::from_millis(30));
        assert_eq!(
            Watchdog::from_period(Duration::from_millis(30)),
            Ok(Watchdog::POWER_UP)
        );
        assert_eq!(Watchdog(1).period(), Duration::from_nanos(5208));
        assert_eq!(
            Watchdog::from_period(Duration::ZERO),
            Ok(Watchdog::DISABLED)
        );
        assert!(Watchdog::DISABLED.is_disabled());
        assert_eq!(
            Watchdog::from_period(Duration::from_nanos(1)),
            Ok(Watchdog(1))
        );
        let max = Watchdog(0xFFFF).period();
        assert_eq!(Watchdog::from_period(max), Ok(Watchdog(0xFFFF)));
        assert!(Watchdog::from_period(Duration::from_millis(342)).is_err());
        assert!(Watchdog::from_period(Duration::MAX).is_err());
    }
}
