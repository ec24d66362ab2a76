//! `firelink demo`: the README's main job. The 28-axis dVRK of seed 000 on
//! emulated boards: configure, power on, home, follow trajectories on all
//! four arms, power off, and report. The run itself is
//! [`firelink_testbed::demo`]; this file parses the options, shows
//! progress and prints the report.

use std::fmt;
use std::io::Write;
use std::path::PathBuf;

use clap::{Args, ValueEnum};
use serde::Serialize;

use firelink_control::config::{IoConfig, JointType, presets};
use firelink_control::runner::Pacing;
use firelink_testbed::demo::{
    DemoFault, DemoOptions, DemoProgress, DemoReport, PortSpec, RealtimeStatus, run_demo,
};
use firelink_wire::human::Number;

use crate::CliError;
use crate::args::{FirmwareArg, ProtocolArg, UdpWaitArg};
use crate::rt;

/// `--fault`: what the demo breaks half way.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FaultArg {
    /// Nothing: the run must end without a fault.
    None,
    /// The host stops sending for three watchdog periods.
    StopHost,
    /// The next broadcast query is corrupted on the wire.
    CorruptQuery,
    /// PSM1's first board stops answering for good.
    BoardLoss,
    /// Joint 0's setpoint jumps further than it can follow.
    FollowingError,
}

impl From<FaultArg> for DemoFault {
    fn from(f: FaultArg) -> DemoFault {
        match f {
            FaultArg::None => DemoFault::None,
            FaultArg::StopHost => DemoFault::StopHost,
            FaultArg::CorruptQuery => DemoFault::CorruptQuery,
            FaultArg::BoardLoss => DemoFault::BoardLoss,
            FaultArg::FollowingError => DemoFault::FollowingError,
        }
    }
}

/// `--pacing`: virtual or wall-clock time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum PacingArg {
    /// As fast as the simulation goes, in virtual time.
    Virtual,
    /// The wall clock.
    Realtime,
}

impl From<PacingArg> for Pacing {
    fn from(p: PacingArg) -> Pacing {
        match p {
            PacingArg::Virtual => Pacing::Virtual,
            PacingArg::Realtime => Pacing::WallClock,
        }
    }
}

/// Options of `firelink demo`.
#[derive(Args, Debug, Clone)]
pub struct DemoArgs {
    /// Which robot: `dvrk` (seed 000's 28 axes on QLA boards), `snake`
    /// (seed 001's 36 axes on its own 7-channel nodes; also chosen by a
    /// `--config` whose boards are SNAKE nodes) or `mahru` (seed 002's
    /// humanoid; it uses --duration, --period-us, --config, --json,
    /// --quiet).
    #[arg(long, value_enum, default_value_t = DemoRobot::Dvrk)]
    pub robot: DemoRobot,
    /// Control rate, Hz (1 to 100000; default 6000, the Snake robot 1000).
    #[arg(long, value_parser = crate::args::rate_hz)]
    pub rate: Option<f64>,
    /// Snake robot: skip the search for the highest rate that holds.
    #[arg(long = "no-rate-search")]
    pub no_rate_search: bool,
    /// MAHRU: the control period in us, 100 to 1000000 (default: its
    /// configuration's 2000).
    #[arg(long = "period-us", value_parser = crate::args::mahru_period_us)]
    pub period_us: Option<f64>,
    /// I/O protocol.
    #[arg(long, value_enum, default_value_t = ProtocolArg::Broadcast)]
    pub protocol: ProtocolArg,
    /// Seconds of motion after homing (above 0, at most a day).
    #[arg(long, default_value_t = 3.0, value_parser = crate::args::run_seconds)]
    pub duration: f64,
    /// Where the boards are: `sim` (the robot's emulated boards on the
    /// simulated bus, in-process; `sim:N[:FW]`: boards 0..N at firmware
    /// FW), `emulate` (the same boards behind an in-process `firelink
    /// emulate`, over loopback UDP), `udp:HOST[:PORT]` (a running
    /// `firelink emulate` or a real bridge board) or `fw` / `fw:N`
    /// (FireWire card 0 / N). MAHRU runs on plain `sim` only.
    #[arg(long, default_value = "sim", value_parser = crate::ports::parse_port)]
    pub port: PortSpec,
    /// Over UDP (`emulate`, `udp:...`): how the port's reads wait for the
    /// answer, `block` (sleep in the kernel, low CPU) or `spin` (poll the
    /// socket, low latency, one core busy while waiting).
    #[arg(long = "udp-wait", value_enum, default_value_t = UdpWaitArg::Block)]
    pub udp_wait: UdpWaitArg,
    /// Board firmware of the emulated boards.
    #[arg(long, value_enum, default_value_t = FirmwareArg::Rev8)]
    pub firmware: FirmwareArg,
    /// Inject a fault half-way.
    #[arg(long, value_enum, default_value_t = FaultArg::None)]
    pub fault: FaultArg,
    /// Pacing; default: virtual for sim, realtime over UDP.
    #[arg(long, value_enum)]
    pub pacing: Option<PacingArg>,
    /// Board watchdog period in ms (above 0, at most 341), or `off`
    /// (a stopped host then leaves the amplifiers on: say so explicitly).
    #[arg(long = "watchdog-ms", default_value = "20", value_parser = crate::args::watchdog)]
    pub watchdog: crate::args::WatchdogSetting,
    /// Do not try SCHED_FIFO, mlockall and a 1 ns timer slack with
    /// realtime pacing.
    #[arg(long = "no-rt")]
    pub no_rt: bool,
    /// The robot configuration (JSON, as in `configs/`); default: seed
    /// 000's dVRK (`configs/dvrk-seed000.json`).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Instead of the trajectories: a teleoperation session, MTMR
    /// driving PSM1 (Large Needle Driver) through the console's
    /// teleoperation for 60 s of virtual time, the clutch pressed from 30
    /// to 33 s (uses --json).
    #[arg(long)]
    pub teleop: bool,
    /// Print the report as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// No progress lines on stderr.
    #[arg(long)]
    pub quiet: bool,
}

impl Default for DemoArgs {
    fn default() -> Self {
        DemoArgs {
            robot: DemoRobot::Dvrk,
            rate: None,
            no_rate_search: false,
            period_us: None,
            protocol: ProtocolArg::Broadcast,
            duration: 3.0,
            port: PortSpec::SIM,
            udp_wait: UdpWaitArg::Block,
            firmware: FirmwareArg::Rev8,
            fault: FaultArg::None,
            pacing: None,
            watchdog: crate::args::WatchdogSetting::default(),
            no_rt: false,
            config: None,
            teleop: false,
            json: false,
            quiet: false,
        }
    }
}

fn progress_line(event: &DemoProgress) -> Option<String> {
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

/// The demo's robots.
#[derive(clap::ValueEnum, Debug, Clone, Copy, PartialEq, Eq)]
pub enum DemoRobot {
    /// Seed 000's da Vinci Research Kit on QLA boards.
    Dvrk,
    /// Seed 001's Snake robot system on its 7-channel nodes.
    Snake,
    /// Seed 002's MAHRU humanoid: 14 modules on three chains, walking.
    Mahru,
}

/// Show one progress event on stderr (ticks overwrite one line).
pub(crate) fn show(event: &DemoProgress, ticking: &mut bool) {
    if let DemoProgress::Tick {
        t,
        cycles,
        io_median_us,
        errors,
    } = event
    {
        eprint!(
            "\rdemo: t = {t:7.3} s  cycles {cycles:8}  io median {io_median_us:6.1} us  errors {errors}   "
        );
        *ticking = true;
        return;
    }
    if std::mem::take(ticking) {
        eprintln!();
    }
    if let Some(line) = progress_line(event) {
        eprintln!("demo: {line}");
    }
}

/// Load a configuration file, printing what its loader warns about (keys
/// Firelink ignores, what the dVRK console would refuse) once, to stderr.
///
/// # Errors
/// The file could not be read, parsed or validated.
pub(crate) fn load_config(path: &std::path::Path) -> Result<IoConfig, CliError> {
    let loaded = IoConfig::load_with_warnings(path)?;
    for w in &loaded.warnings {
        eprintln!("warning: {w}");
    }
    Ok(loaded.config)
}

/// The demo's options from the command line.
///
/// # Errors
/// The configuration file could not be loaded.
pub fn options(args: &DemoArgs) -> Result<DemoOptions, CliError> {
    let config = match &args.config {
        Some(path) => load_config(path)?,
        None => presets::dvrk_seed000(),
    };
    let watchdog = args.watchdog;
    Ok(DemoOptions {
        config,
        rate_hz: args.rate.unwrap_or(6000.0),
        protocol: args.protocol.into(),
        duration_s: args.duration,
        port: args.port,
        firmware: args.firmware.into(),
        fault: args.fault.into(),
        pacing: args.pacing.map(Pacing::from),
        watchdog,
        udp_wait: args.udp_wait.into(),
    })
}

/// The real-time settings for the thread that runs the cycles;
/// `spinning`: its port's reads spin (see [`rt::setup`]).
pub(crate) fn realtime_setup(spinning: bool) -> RealtimeStatus {
    let s = rt::setup(80, spinning);
    RealtimeStatus {
        requested: true,
        sched_fifo_priority: s.sched_fifo,
        memory_locked: s.memory_locked,
        timer_slack_1ns: s.timer_slack_1ns,
        errors: s.errors,
    }
}

/// Run a demo with its progress on stderr (unless quiet): `run` gets the
/// real-time setup to call (unless `--no-rt`) and the progress sink.
pub(crate) fn with_progress<T>(
    args: &DemoArgs,
    run: impl FnOnce(
        Option<&dyn Fn() -> RealtimeStatus>,
        &mut dyn FnMut(DemoProgress),
    ) -> Result<T, firelink_testbed::TestbedError>,
) -> Result<T, CliError> {
    let quiet = args.quiet || crate::args::quiet();
    if let Some(w) = args.watchdog.warning() {
        eprintln!("demo: {w}");
    }
    // The port's reads spin over UDP with `--udp-wait spin`.
    let spinning = args.udp_wait == UdpWaitArg::Spin && !args.port.is_sim();
    let setup_spinning = move || realtime_setup(spinning);
    let setup: &dyn Fn() -> RealtimeStatus = &setup_spinning;
    let mut ticking = false;
    let report = run((!args.no_rt).then_some(setup), &mut |event| {
        if !quiet {
            show(&event, &mut ticking);
        }
    })?;
    if ticking {
        eprintln!();
    }
    Ok(report)
}

/// Print a demo's report: JSON with `--json`, else the table.
pub(crate) fn print_report(
    args: &DemoArgs,
    out: &mut impl Write,
    report: &(impl Serialize + fmt::Display),
) -> Result<(), CliError> {
    if args.json {
        writeln!(out, "{}", serde_json::to_string(report)?)?;
    } else {
        write!(out, "{report}")?;
    }
    Ok(())
}

/// Run `firelink demo`.
pub fn run(args: &DemoArgs, out: &mut impl Write) -> Result<(), CliError> {
    if args.teleop {
        return run_teleop(args, out);
    }
    if args.robot == DemoRobot::Mahru {
        return crate::mahru_cmd::run_demo(args, out);
    }
    if crate::snake_demo::wanted(args)? {
        return crate::snake_demo::run(args, out);
    }
    let options = options(args)?;
    let report = with_progress(args, |rt, progress| run_demo(&options, rt, progress))?;
    if !(args.quiet || crate::args::quiet()) && report.realtime.requested {
        let r = &report.realtime;
        eprintln!(
            "demo: real time: SCHED_FIFO {}, memory locked {}, timer slack 1 ns {}{}",
            r.sched_fifo_priority.is_some(),
            r.memory_locked,
            r.timer_slack_1ns,
            if r.errors.is_empty() {
                String::new()
            } else {
                format!(" ({})", r.errors.join("; "))
            }
        );
    }
    if args.json {
        print_report(args, out, &report)?;
    } else {
        write!(out, "{}", render(&report, &options.config))?;
    }
    report.verdict().map_err(CliError::Failed)
}

/// `firelink demo --teleop`: the teleoperation session and its report.
fn run_teleop(args: &DemoArgs, out: &mut impl Write) -> Result<(), CliError> {
    use firelink_testbed::teleop::TeleopOptions;
    if !(args.quiet || crate::args::quiet()) {
        eprintln!(
            "demo: teleoperation MTMR -> PSM1, 60 s of virtual time on the simulated bus \
             (the clutch pressed from 30 to 33 s)"
        );
    }
    let options = TeleopOptions {
        firmware: args.firmware.into(),
        ..TeleopOptions::default()
    };
    let report = firelink_testbed::teleop::run_teleop(&options)?;
    if args.json {
        serde_json::to_writer_pretty(&mut *out, &report)
            .map_err(|e| CliError::Failed(e.to_string()))?;
        writeln!(out)?;
    } else {
        write!(out, "{report}")?;
    }
    Ok(())
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
    let (total, e) = (report.errors.total, &report.errors.by_kind);
    let _ = writeln!(
        s,
        "  errors: total {}  timeouts {}  sequence {}  corrupt queries {}  bus resets {}  bad packets {}  nacks {}",
        total,
        e.timeouts,
        e.sequence_errors,
        e.corrupt_queries,
        e.bus_resets,
        e.bad_packets,
        e.nacks
    );
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
    use firelink_testbed::demo::TimeStats;

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
