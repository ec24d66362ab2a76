//! `firelink soak`: the fault soak and the watchdog proof
//! ([`firelink_testbed::soak`], [`firelink_testbed::watchdog`]).

use std::io::Write;

use clap::Args;

use firelink_testbed::soak::{self, SoakReport, SoakSettings};
use firelink_testbed::watchdog::{self, WatchdogReport};

use crate::error::CliError;

/// Options of `firelink soak`.
#[derive(Args, Debug)]
pub struct SoakArgs {
    /// Servo cycles of the 28-axis robot (virtual time, 6 kHz).
    #[arg(long, default_value_t = 1_000_000, value_parser = crate::args::cycles)]
    pub cycles: u64,
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
        ..SoakSettings::default()
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
        print_report(out, &report, proof.as_ref())?;
    }
    let failed = !report.passed() || proof.as_ref().is_some_and(|p| !p.passed());
    if failed {
        return Err(CliError::Failed(
            "the soak found unaccounted faults or a broken safety invariant".into(),
        ));
    }
    Ok(())
}

fn print_report(
    out: &mut impl Write,
    r: &SoakReport,
    proof: Option<&WatchdogReport>,
) -> std::io::Result<()> {
    writeln!(
        out,
        "fault soak: {} cycles ({:.1} s virtual), seed {}, {} packets, {} faults ({:.2} % of packets)",
        r.cycles,
        r.virtual_s,
        r.seed,
        r.packets,
        r.injected,
        100.0 * r.packet_fault_share
    )?;
    writeln!(
        out,
        "  detected {}  harmless {}  undetected {}",
        r.detected, r.harmless, r.undetected
    )?;
    writeln!(
        out,
        "  bad commands applied {}  amplifier on after off {}  (cycles waiting for the off acknowledgement {})",
        r.bad_commands_applied, r.amplifier_on_after_off, r.disable_pending_cycles
    )?;
    writeln!(
        out,
        "  robot faults {}  re-armed {}",
        r.robot_faults, r.rearms
    )?;
    writeln!(
        out,
        "  {:<26} {:>9} {:>9} {:>9} {:>10}",
        "fault", "injected", "detected", "harmless", "undetected"
    )?;
    for (name, o) in &r.by_fault {
        writeln!(
            out,
            "  {name:<26} {:>9} {:>9} {:>9} {:>10}",
            o.injected, o.detected, o.harmless, o.undetected
        )?;
    }
    for e in &r.undetected_examples {
        writeln!(out, "  UNDETECTED: {e}")?;
    }
    if let Some(p) = proof {
        writeln!(
            out,
            "watchdog proof: {} host stops x 8 boards: {} of {} off within period {:.1} us + one tick {:.3} us",
            p.trials, p.within_bound, p.observations, p.period_us, p.tick_us
        )?;
        let [min, p50, p99, max] = p.over_period_us;
        writeln!(
            out,
            "  off after the last write, minus the period (us): min {min:.3}  median {p50:.3}  p99 {p99:.3}  max {max:.3}"
        )?;
        let [min, p50, p99, max] = p.after_stop_us;
        writeln!(
            out,
            "  off after the host stopped (us): min {min:.1}  median {p50:.1}  p99 {p99:.1}  max {max:.1}"
        )?;
    }
    Ok(())
}
