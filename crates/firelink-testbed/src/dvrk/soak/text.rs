//! The soak's report and the watchdog proof as text: the tables
//! `firelink soak` prints (any front end may show the same).

use std::fmt;

use super::SoakReport;
use crate::dvrk::watchdog::WatchdogReport;

impl fmt::Display for SoakReport {
    fn fmt(&self, out: &mut fmt::Formatter<'_>) -> fmt::Result {
        let r = self;
        writeln!(
            out,
            "fault soak: {} cycles of {:.3} us ({:.1} s virtual), seed {}, {} packets, {} faults ({:.2} % of packets)",
            r.cycles,
            r.period_us,
            r.virtual_s,
            r.seed,
            r.packets,
            r.injected,
            100.0 * r.packet_fault_share
        )?;
        writeln!(out, "  {}", r.detail)?;
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
        Ok(())
    }
}

impl fmt::Display for WatchdogReport {
    fn fmt(&self, out: &mut fmt::Formatter<'_>) -> fmt::Result {
        let p = self;
        writeln!(
            out,
            "watchdog proof: {} host stops x 8 boards, servo period {:.3} us: {} of {} off within period {:.1} us + one tick {:.3} us",
            p.trials, p.servo_period_us, p.within_bound, p.observations, p.period_us, p.tick_us
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
        )
    }
}
