//! `firelink demo`: the README's main job. The 28-axis dVRK of seed 000 on
//! emulated boards ([`dvrk`]): configure, power on, home, follow
//! trajectories on all four arms, power off, and report; or seed 001's
//! Snake system ([`snake`]), or seed 002's MAHRU humanoid walking
//! ([`mahru`], which also holds `firelink budget`). The runs themselves
//! are in the testbed; [`robot`] picks one.
//!
//! This file holds what the robots share: the options, the progress
//! shown on stderr, the real-time setup and the report's printing. The
//! robots' files import it and nothing here imports them.

pub mod dvrk;
pub mod mahru;
pub mod robot;
pub mod snake;

use std::fmt;
use std::io::Write;
use std::path::PathBuf;

use clap::{Args, ValueEnum};
use serde::Serialize;

use firelink_control::config::IoConfig;
use firelink_control::runner::Pacing;
use firelink_testbed::demo::{DemoFault, DemoProgress, PortSpec, RealtimeStatus};
use firelink_testbed::fault_script::FaultScript;

use crate::args::{FirmwareArg, ProtocolArg, UdpWaitArg};
use crate::error::CliError;
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
    /// Inject a fault half-way (a named preset: its fault script).
    #[arg(long, value_enum, default_value_t = FaultArg::None)]
    pub fault: FaultArg,
    /// Instead of --fault: faults as a plan, entries separated by `;`.
    /// `start` is the motion's first cycle, `cycle=N` counts the motion's
    /// cycles, `t=` counts from half way: `mute@cycle=300:id=4`,
    /// `host-pause@t=0us:for=60000us`,
    /// `corrupt@t=0us:tcode=0x0,offset=0x1800,count=1`,
    /// `drop@cycle=100:dest=2,rate=0.1` (a port that cannot apply an entry
    /// refuses it by name before the run).
    #[arg(long = "faults", value_name = "SCRIPT", conflicts_with = "fault")]
    pub faults: Option<FaultScript>,
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
            faults: None,
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
