//! One soak request: the soak's settings and the watchdog proof after it,
//! as `firelink soak` asks for them ([`SoakRequest`], clap's `Args` behind
//! the `clap` feature), and what the two runs found ([`SoakOutcome`]: its
//! JSON, its text and the verdict).

use std::fmt;

use firelink_bus::Detail;
use firelink_control::ServoPeriod;

use super::{SoakReport, SoakSettings};
use crate::TestbedError;
use crate::dvrk::watchdog::{self, WatchdogReport};

/// A soak's servo period must be shorter than the boards' watchdog (the
/// default 20 ms the soak and the proof keep): a longer one would trip it
/// between two cycles of a healthy loop.
///
/// # Errors
/// [`TestbedError::Config`], naming both.
pub fn watchdog_allows(period: ServoPeriod) -> Result<(), TestbedError> {
    let watchdog = firelink_host::WatchdogSetting::default().period_or_zero();
    if period.as_duration() >= watchdog {
        return Err(TestbedError::Config(format!(
            "soak --period {period}: the boards' watchdog is {} ms; the servo period must be shorter",
            watchdog.as_secs_f64() * 1e3
        )));
    }
    Ok(())
}

/// The soak and the watchdog proof, as asked for.
#[derive(Debug, Clone)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
pub struct SoakRequest {
    /// Servo cycles of the 28-axis robot (virtual time, one --period each).
    #[cfg_attr(
        feature = "clap",
        arg(long, default_value_t = 1_000_000, value_parser = crate::limits::cycles)
    )]
    pub cycles: u64,
    /// The servo period, as a period or a rate: `1ms`, `250us`, `6kHz`
    /// (10 us to under the boards' 20 ms watchdog).
    #[cfg_attr(
        feature = "clap",
        arg(long, default_value = "6kHz", value_parser = crate::limits::soak_servo_period)
    )]
    pub period: ServoPeriod,
    /// Seed of every random choice: the same seed gives the same report.
    #[cfg_attr(feature = "clap", arg(long, default_value_t = 1))]
    pub seed: u64,
    /// Chance that a packet of the I/O cycle is faulted (0..=1).
    #[cfg_attr(
        feature = "clap",
        arg(long = "packet-fault-rate", default_value_t = 0.01, value_parser = crate::limits::probability)
    )]
    pub packet_fault_rate: f64,
    /// One bus-level fault (reset, babble, unplug) per this many cycles on
    /// average.
    #[cfg_attr(
        feature = "clap",
        arg(long = "bus-fault-every", default_value_t = 2_000, value_parser = crate::limits::cycles)
    )]
    pub bus_fault_every: u64,
    /// Host-stop moments for the watchdog proof (0: skip it).
    #[cfg_attr(
        feature = "clap",
        arg(long = "watchdog-trials", default_value_t = 1_000)
    )]
    pub watchdog_trials: u64,
    /// The simulated bus's level of detail: `fast` (a packet's deliveries
    /// in one batch where that is exact) or `packet` (every delivery an
    /// event of its own); the same report either way but for its count of
    /// which ran.
    #[cfg_attr(feature = "clap", arg(long, default_value = "fast"))]
    pub detail: Detail,
}

impl Default for SoakRequest {
    /// The soak's default settings, then 1000 host stops.
    fn default() -> Self {
        let settings = SoakSettings::default();
        SoakRequest {
            cycles: settings.cycles,
            period: settings.period,
            seed: settings.seed,
            packet_fault_rate: settings.packet_fault_rate,
            bus_fault_every: settings.bus_fault_every,
            watchdog_trials: 1_000,
            detail: settings.detail,
        }
    }
}

/// What the soak and the watchdog proof found.
#[derive(Debug, Clone)]
pub struct SoakOutcome {
    /// The soak's report.
    pub soak: SoakReport,
    /// The watchdog proof's, when it ran.
    pub watchdog: Option<WatchdogReport>,
}

impl SoakRequest {
    /// The soak's settings.
    pub fn settings(&self) -> SoakSettings {
        SoakSettings {
            cycles: self.cycles,
            seed: self.seed,
            packet_fault_rate: self.packet_fault_rate,
            bus_fault_every: self.bus_fault_every,
            period: self.period,
            detail: self.detail,
        }
    }

    /// The servo period must be shorter than the boards' watchdog
    /// ([`watchdog_allows`]).
    ///
    /// # Errors
    /// [`TestbedError::Config`], naming both.
    pub fn check_period(&self) -> Result<(), TestbedError> {
        watchdog_allows(self.period)
    }

    /// Run the soak, then the watchdog proof (unless `watchdog_trials` is
    /// 0) with the same seed; `progress` gets a line now and then (the
    /// cycles and faults so far, the proof starting).
    ///
    /// # Errors
    /// As [`super::run`] and [`watchdog::run`].
    pub fn run(&self, progress: &mut dyn FnMut(&str)) -> Result<SoakOutcome, TestbedError> {
        self.check_period()?;
        let soak = super::run(&self.settings(), |done, r| {
            progress(&format!(
                "{done} cycles, {} faults ({} detected, {} harmless, {} undetected)",
                r.injected, r.detected, r.harmless, r.undetected
            ));
        })?;
        let watchdog = if self.watchdog_trials > 0 {
            progress(&format!(
                "watchdog proof, {} host stops",
                self.watchdog_trials
            ));
            Some(watchdog::run(self.watchdog_trials, self.seed, self.period)?)
        } else {
            None
        };
        Ok(SoakOutcome { soak, watchdog })
    }
}

impl SoakOutcome {
    /// Whether every fault was accounted for, both safety invariants held
    /// and the watchdog proof (if it ran) passed.
    pub fn passed(&self) -> bool {
        self.soak.passed() && self.watchdog.as_ref().is_none_or(WatchdogReport::passed)
    }

    /// Both reports and the verdict as one JSON object (keys `passed`,
    /// `soak`, `watchdog`).
    ///
    /// # Errors
    /// Serialisation (not expected: the reports are plain data).
    pub fn json(&self) -> Result<String, serde_json::Error> {
        serde_json::to_string(&serde_json::json!({
            "soak": self.soak,
            "watchdog": self.watchdog,
            "passed": self.passed(),
        }))
    }

    /// The verdict, for a front end's exit status.
    ///
    /// # Errors
    /// One line: a fault went unaccounted for or a safety invariant broke.
    pub fn verdict(&self) -> Result<(), String> {
        if self.passed() {
            Ok(())
        } else {
            Err("the soak found unaccounted faults or a broken safety invariant".into())
        }
    }
}

impl fmt::Display for SoakOutcome {
    /// The soak's table, then the watchdog proof's.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.soak)?;
        if let Some(proof) = &self.watchdog {
            write!(f, "{proof}")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_period_the_watchdog_would_trip_on_is_refused_before_the_run() {
        let request = |period: &str| SoakRequest {
            period: period.parse().unwrap(),
            ..SoakRequest::default()
        };
        let e = request("25ms").run(&mut |_| {}).unwrap_err();
        assert_eq!(
            e.to_string(),
            "configuration: soak --period 25 ms: the boards' watchdog is 20 ms; the servo period must be shorter"
        );
        assert!(request("20ms").check_period().is_err());
        assert!(request("19ms").check_period().is_ok());
        assert!(SoakRequest::default().check_period().is_ok());
        // The option's parser refuses the same (a usage error).
        let e = crate::limits::soak_servo_period("20ms").unwrap_err();
        assert!(e.contains("watchdog is 20 ms"), "{e}");
        assert!(crate::limits::soak_servo_period("19ms").is_ok());
    }

    #[test]
    fn the_request_carries_the_soaks_settings() {
        let defaults = SoakSettings::default();
        let settings = SoakRequest::default().settings();
        assert_eq!(settings.cycles, defaults.cycles);
        assert_eq!(settings.seed, defaults.seed);
        assert_eq!(settings.packet_fault_rate, defaults.packet_fault_rate);
        assert_eq!(settings.bus_fault_every, defaults.bus_fault_every);
        assert_eq!(settings.period, defaults.period);
        // Every field not its default, so a dropped one shows.
        let period: ServoPeriod = "1ms".parse().unwrap();
        assert_ne!(period, defaults.period);
        assert_ne!(defaults.packet_fault_rate, 0.25);
        assert_ne!(defaults.bus_fault_every, 777);
        let settings = SoakRequest {
            cycles: 5,
            seed: 9,
            packet_fault_rate: 0.25,
            bus_fault_every: 777,
            period,
            ..SoakRequest::default()
        }
        .settings();
        assert_eq!((settings.cycles, settings.seed), (5, 9));
        assert_eq!(settings.packet_fault_rate, 0.25);
        assert_eq!(settings.bus_fault_every, 777);
        assert_eq!(settings.period, period);
    }

    #[cfg(feature = "clap")]
    fn period_of(args: &[&str]) -> Result<ServoPeriod, String> {
        use clap::{Args, FromArgMatches};
        let command = SoakRequest::augment_args(clap::Command::new("soak"));
        command
            .try_get_matches_from([&["soak"], args].concat())
            .and_then(|m| SoakRequest::from_arg_matches(&m))
            .map(|r| r.period)
            .map_err(|e| e.to_string())
    }

    #[cfg(feature = "clap")]
    #[test]
    fn the_period_is_a_period_or_a_rate_under_the_one_rule() {
        assert_eq!(
            period_of(&[]).unwrap(),
            ServoPeriod::from_rate_hz(6000.0).unwrap()
        );
        assert_eq!(period_of(&["--period", "1ms"]).unwrap(), ServoPeriod::KHZ_1);
        assert_eq!(
            period_of(&["--period", "1kHz"]).unwrap(),
            ServoPeriod::KHZ_1
        );
        for bad in ["5us", "2s", "0Hz"] {
            let e = period_of(&["--period", bad]).unwrap_err();
            assert!(
                e.contains("out of range, 10 us to 1 s (100 kHz to 1 Hz)"),
                "{bad}: {e}"
            );
        }
    }

    /// The request's `Default` is the command line's defaults.
    #[cfg(feature = "clap")]
    #[test]
    fn the_default_is_what_the_command_line_gives_with_no_options() {
        use clap::{Args, FromArgMatches};
        let command = SoakRequest::augment_args(clap::Command::new("soak"));
        let parsed = SoakRequest::from_arg_matches(&command.get_matches_from(["soak"])).unwrap();
        assert_eq!(
            format!("{parsed:?}"),
            format!("{:?}", SoakRequest::default())
        );
    }
}
