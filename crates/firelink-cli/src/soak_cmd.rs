//! `firelink soak`: the fault soak and the watchdog proof
//! ([`firelink_testbed::dvrk::soak`], [`firelink_testbed::dvrk::watchdog`]).

use std::io::Write;

use clap::Args;

use firelink_control::ServoPeriod;

use firelink_testbed::dvrk::soak::{self, SoakSettings};
use firelink_testbed::dvrk::watchdog::{self, WatchdogReport};

use crate::error::CliError;

/// Options of `firelink soak`.
#[derive(Args, Debug)]
pub struct SoakArgs {
    /// Servo cycles of the 28-axis robot (virtual time, one --period each).
    #[arg(long, default_value_t = 1_000_000, value_parser = crate::args::cycles)]
    pub cycles: u64,
    /// The servo period, as a period or a rate: `1ms`, `250us`, `6kHz`
    /// (10 us to 1 s).
    #[arg(long, default_value = "6kHz")]
    pub period: ServoPeriod,
    /// Seed of every random choice: the same seed gives the same report.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Chance that a packet of the I/O cycle is faulted (0..=1).
    #[arg(long = "packet-fault-rate", default_value_t = 0.01, value_parser = crate::args::probability)]
    pub packet_fault_rate: f64,
    /// One bus-level fault (reset, babble, unplug) per this many cycles on
    /// average.
    #[arg(long = "bus-fault-every", default_value_t = 2_000, value_parser = crate::args::cycles)]
    pub bus_fault_every: u64,
    /// Host-stop moments for the watchdog proof (0: skip it).
    #[arg(long = "watchdog-trials", default_value_t = 1_000)]
    pub watchdog_trials: u64,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Run `firelink soak`; exits non-zero when a fault went unaccounted for
/// or a safety invariant broke.
pub fn run(args: &SoakArgs, out: &mut impl Write) -> Result<(), CliError> {
    let quiet = crate::args::quiet();
    let settings = SoakSettings {
        cycles: args.cycles,
        seed: args.seed,
        packet_fault_rate: args.packet_fault_rate,
        bus_fault_every: args.bus_fault_every,
        period: args.period,
    };
    let report = soak::run(&settings, |done, r| {
        if !quiet {
            eprintln!(
                "soak: {done} cycles, {} faults ({} detected, {} harmless, {} undetected)",
                r.injected, r.detected, r.harmless, r.undetected
            );
        }
    })?;
    let proof = if args.watchdog_trials > 0 {
        if !quiet {
            eprintln!("soak: watchdog proof, {} host stops", args.watchdog_trials);
        }
        Some(watchdog::run(args.watchdog_trials, args.seed)?)
    } else {
        None
    };
    if args.json {
        writeln!(
            out,
            "{}",
            serde_json::to_string(&serde_json::json!({
                "soak": report,
                "watchdog": proof,
                "passed": report.passed() && proof.as_ref().is_none_or(WatchdogReport::passed),
            }))?
        )?;
    } else {
        write!(out, "{report}")?;
        if let Some(proof) = &proof {
            write!(out, "{proof}")?;
        }
    }
    let failed = !report.passed() || proof.as_ref().is_some_and(|p| !p.passed());
    if failed {
        return Err(CliError::Failed(
            "the soak found unaccounted faults or a broken safety invariant".into(),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `firelink soak`'s arguments alone.
    #[derive(clap::Parser, Debug)]
    struct Soak {
        #[command(flatten)]
        args: SoakArgs,
    }

    fn period_of(args: &[&str]) -> Result<ServoPeriod, String> {
        use clap::Parser;
        Soak::try_parse_from([&["soak"], args].concat())
            .map(|s| s.args.period)
            .map_err(|e| e.to_string())
    }

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
}
