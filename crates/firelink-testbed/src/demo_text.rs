//! The dVRK demo as a person reads it: a progress event as a line
//! ([`progress_line`]; a tick as the line a display redraws in place,
//! [`tick_line`]) and the report as a table ([`render`], the errors in
//! one line, [`ErrorCounts`](crate::demo::ErrorCounts)'s `Display`), with what its timing means in words
//! ([`timing_notes`]). `firelink demo` prints these; `--json` prints the
//! [`DemoReport`] itself.

use firelink_control::config::{IoConfig, JointType};
use firelink_wire::human::Number;

use crate::demo::{DemoProgress, DemoReport};

/// A [`DemoProgress::Tick`] as the one line a display redraws in place
/// (`None` for every other event).
pub fn tick_line(event: &DemoProgress) -> Option<String> {
    let DemoProgress::Tick {
        t,
        cycles,
        io_median_us,
        errors,
    } = event
    else {
        return None;
    };
    Some(format!(
        "t = {t:7.3} s  cycles {cycles:8}  io median {io_median_us:6.1} us  errors {errors}"
    ))
}

/// A progress event as one line for a person (`None`: nothing to show,
/// e.g. a [`DemoProgress::Tick`], which a display draws in place).
pub fn progress_line(event: &DemoProgress) -> Option<String> {
    Some(match event {
        DemoProgress::Found {
            boards,
            port,
            reason,
            protocol,
        } => format!("found {boards} boards on {port} ({reason}), protocol {protocol}"),
        DemoProgress::WatchdogOff => return None,
        DemoProgress::TookOver(text) => text.clone(),
        DemoProgress::Configured => "configured; powering on".into(),
        DemoProgress::Powered(t) => format!("powered at t = {t:.3} s; homing"),
        DemoProgress::Homed(t) => format!("homed and active at t = {t:.3} s; moving every arm"),
        DemoProgress::Tick { .. } => return None,
        DemoProgress::Injecting(f) => format!("injecting fault: {f}"),
        DemoProgress::Fault(text) => format!("FAULT: {text}"),
        DemoProgress::SafetyChain {
            state,
            amplifiers_on,
        } => format!(
            "safety chain: state {state}, amplifiers {}",
            if *amplifiers_on { "ON" } else { "off" }
        ),
        DemoProgress::PoweredOff(wall) => format!("powered off; wall time {wall:.2} s"),
    })
}

/// A time in microseconds as a person reads it: `183.4 us`, `24.1 ms`.
fn time(us: f64) -> String {
    if us >= 1000.0 {
        format!("{:.1} ms", us / 1000.0)
    } else {
        format!("{us:.1} us")
    }
}

/// How much longer than the cycle's 99th percentile a cycle must be, and
/// longer than the control period, to count as a stall of the machine
/// rather than the cycle's own work.
const STALL_FACTOR: f64 = 4.0;

/// What the report's timing means, in words: what "cycle time" adds up,
/// whether its maximum is a stall of the machine, and what "late cycles"
/// count. Cycle time is the I/O time on the port's clock (virtual on the
/// simulated bus) plus the compute time on the machine's monotonic clock
/// (`firelink_control::runner::CycleTimes`); late cycles are counted only
/// with wall-clock pacing: cycles the host started more than half a
/// period after their deadline (the schedule then restarts from there).
pub fn timing_notes(report: &DemoReport) -> Vec<String> {
    let period_us = 1e6 / report.rate_hz;
    let virtual_pacing = report.pacing == "virtual";
    let mut notes = vec![if virtual_pacing {
        "cycle time = I/O time on the port's clock (simulated) + compute time on the machine's clock"
            .to_string()
    } else {
        "cycle time = I/O time + compute time, both on the machine's clock".to_string()
    }];
    let c = &report.cycle_time_us;
    if c.max > period_us && c.max > STALL_FACTOR * c.p99 {
        let part = if report.compute_time_us.max >= 0.5 * c.max {
            "in the compute part"
        } else {
            "in the I/O part"
        };
        let effect = if virtual_pacing {
            "with virtual pacing the robot's clock never saw it"
        } else {
            "the cycle after it starts late"
        };
        notes.push(format!(
            "max {}: the machine stalled {part} (OS preemption, a page fault or another \
             process held up the host thread), not the cycle's work (99 % of cycles took at \
             most {}); {effect}",
            time(c.max),
            time(c.p99)
        ));
    }
    notes.push(if virtual_pacing {
        "late cycles: not counted with virtual pacing (the port's clock waits for the host, so \
         no cycle starts late)"
            .to_string()
    } else {
        format!(
            "late cycles {}: cycles the host started more than half a period ({}) after their \
             deadline (wall-clock pacing)",
            report.overruns,
            time(period_us / 2.0)
        )
    });
    notes
}

/// The demo's report as a table (`--json` prints the report itself). An
/// arm's prismatic tracking error is shown only if the configuration
/// gives it a prismatic joint (an MTM has none).
pub fn render(report: &DemoReport, config: &IoConfig) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let arms: Vec<&str> = report.tracking_error.keys().map(String::as_str).collect();
    let _ = writeln!(
        s,
        "Firelink demo: {} axes ({})",
        report.axes,
        arms.join(", ")
    );
    let _ = writeln!(
        s,
        "  port {}  boards {}  axes {}  firmware {}  protocol {}  rate {} Hz  pacing {}",
        report.port,
        report.boards,
        report.axes,
        report.firmware.map_or("?".to_string(), |v| v.to_string()),
        report.protocol,
        Number(report.rate_hz),
        report.pacing
    );
    let _ = writeln!(
        s,
        "  cycles {} ({} with motion), {:.3} s on the port's clock, {:.2} s wall ({:.2}x real time)",
        report.cycles,
        report.motion_cycles,
        report.port_time_s,
        report.wall_time_s,
        report.speed_vs_real_time
    );
    if let Some(detail) = &report.detail {
        let _ = writeln!(s, "  {detail}");
    }
    for (name, p) in [
        ("cycle time", &report.cycle_time_us),
        ("I/O time", &report.io_time_us),
        ("compute", &report.compute_time_us),
    ] {
        let _ = writeln!(
            s,
            "  {name:<10} median {:8.2} us  p99 {:8.2} us  max {:8.2} us",
            p.median, p.p99, p.max
        );
    }
    for note in timing_notes(report) {
        let _ = writeln!(s, "  {note}");
    }
    let _ = writeln!(
        s,
        "  tracking error, RMS (max): revolute joints in rad, prismatic joints in mm"
    );
    for (arm, t) in &report.tracking_error_detail {
        let prismatic = config.robot(arm).is_some_and(|r| {
            r.actuators
                .iter()
                .any(|a| a.joint_type == Some(JointType::Prismatic))
        });
        let _ = write!(s, "    {arm:<5} {:.5} rad ({:.5})", t.rms_rad, t.max_rad);
        if prismatic {
            let _ = write!(
                s,
                "  prismatic {:.3} mm ({:.3})",
                t.prismatic_rms_mm, t.prismatic_max_mm
            );
        }
        let _ = writeln!(s);
    }
    let _ = writeln!(s, "  {}", report.errors);
    let w = &report.watchdog;
    let period = if w.period_ms > 0.0 {
        format!("{} ms", Number(w.period_ms))
    } else {
        "off".to_string()
    };
    let expired = if w.expired_boards.is_empty() {
        "no board".to_string()
    } else {
        let ids: Vec<String> = w.expired_boards.iter().map(u8::to_string).collect();
        format!("boards {}", ids.join(", "))
    };
    let _ = writeln!(s, "  watchdog: {period}; expired on {expired}");
    match &report.fault {
        None => {
            let _ = writeln!(s, "  faults: none; final state {}", report.state);
        }
        Some(fl) => {
            let _ = writeln!(
                s,
                "  FAULT ({} injected): {}\n  safety chain: left active, amplifiers {}",
                report.fault_injected,
                fl.text,
                if report.amplifiers_on_after_fault == Some(true) {
                    "STILL ON"
                } else {
                    "off"
                }
            );
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::demo::TimeStats;
    use crate::dvrk::demo::{DemoOptions, run_demo};

    /// A short run of the dVRK demo on the simulated bus.
    fn report() -> (DemoReport, IoConfig) {
        let options = DemoOptions {
            duration_s: 0.02,
            ..DemoOptions::default()
        };
        let report = run_demo(&options, None, |_| {}).expect("a demo run");
        (report, options.config)
    }

    #[test]
    fn timing_says_what_late_counts_and_marks_stalls() {
        let (mut r, config) = report();
        r.cycle_time_us = TimeStats {
            median: 120.0,
            p99: 180.0,
            max: 24_100.0,
            mean: 130.0,
        };
        r.compute_time_us.max = 24_000.0;
        let text = render(&r, &config);
        assert!(
            text.contains(
                "max 24.1 ms: the machine stalled in the compute part (OS preemption, a page \
                 fault or another process held up the host thread), not the cycle's work \
                 (99 % of cycles took at most 180.0 us); with virtual pacing the robot's clock \
                 never saw it"
            ),
            "{text}"
        );
        assert!(
            text.contains("late cycles: not counted with virtual pacing"),
            "{text}"
        );
        r.pacing = "realtime".into();
        r.overruns = 1;
        let notes = timing_notes(&r).join("\n");
        assert!(notes.contains("the cycle after it starts late"), "{notes}");
        assert!(
            notes.contains(
                "late cycles 1: cycles the host started more than half a period (83.3 us) \
                 after their deadline"
            ),
            "{notes}"
        );
        // An ordinary maximum is not called a stall.
        r.cycle_time_us.max = 200.0;
        assert!(!timing_notes(&r).join("\n").contains("stalled"));
    }

    #[test]
    fn only_arms_with_a_prismatic_joint_report_one() {
        let (r, config) = report();
        let text = render(&r, &config);
        for line in text.lines().filter(|l| l.trim_start().starts_with("MTM")) {
            assert!(!line.contains("prismatic"), "{line}");
        }
        for line in text.lines().filter(|l| l.trim_start().starts_with("PSM")) {
            assert!(line.contains("prismatic"), "{line}");
        }
        assert!(
            text.contains("watchdog: 20 ms; expired on no board"),
            "{text}"
        );
    }
}
