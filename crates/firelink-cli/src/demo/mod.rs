//! `firelink demo`: the README's main job. The 28-axis dVRK of seed 000 on
//! emulated boards: configure, power on, home, follow trajectories on all
//! four arms, power off, and report; or seed 001's Snake system, or seed
//! 002's MAHRU humanoid walking ([`mahru`] also holds `firelink budget`).
//! The runs, the choice of robot and the report's table are the testbed's
//! ([`firelink_testbed::demo_request`]); [`robot`] runs the request.
//!
//! This file holds the options and the progress shown on stderr (the
//! real-time setup is the testbed's `RealtimeStatus::take`).

pub mod mahru;
pub mod robot;

use std::path::PathBuf;

use clap::{Args, FromArgMatches};

use firelink_control::ServoPeriod;
use firelink_control::config::IoConfig;
use firelink_control::runner::Pacing;
use firelink_host::scan::Protocol;
use firelink_host::udp::WaitMode;
use firelink_testbed::demo::{DemoFault, DemoProgress, PortSpec};
use firelink_testbed::demo_text::{progress_line, tick_line};
use firelink_testbed::emulated::Profile;
use firelink_testbed::fault_script::FaultScript;
use firelink_testbed::rig::RobotKind;

use crate::error::CliError;

/// Options of `firelink demo`.
#[derive(Args, Debug, Clone)]
pub struct DemoArgs {
    /// Which robot: `dvrk` (seed 000's 28 axes on QLA boards), `snake`
    /// (seed 001's 36 axes on its own 7-channel nodes; also chosen by a
    /// `--config` whose boards are SNAKE nodes) or `mahru` (seed 002's
    /// humanoid; it uses --duration, --period, --config, --json,
    /// --quiet).
    #[arg(long, value_enum, default_value_t = RobotKind::Dvrk)]
    pub robot: RobotKind,
    /// The servo period for every robot, as a period or a rate: `1ms`,
    /// `250us`, `6kHz` (10 us to 1 s; default: the dVRK 6 kHz, the Snake
    /// robot 1 kHz, MAHRU its configuration's 2 ms).
    #[arg(long, conflicts_with_all = ["rate", "period_us"])]
    pub period: Option<ServoPeriod>,
    /// The period as a rate in Hz (the older spelling of --period).
    #[arg(long, hide = true, value_parser = crate::args::servo_rate, conflicts_with = "period_us")]
    pub rate: Option<ServoPeriod>,
    /// The period in us, 100 to 1000000 (the older spelling of --period).
    #[arg(long = "period-us", hide = true, value_parser = crate::args::servo_period_us)]
    pub period_us: Option<ServoPeriod>,
    /// Snake robot and MAHRU: skip the search for the fastest rate or
    /// period that holds.
    #[arg(long = "no-rate-search")]
    pub no_rate_search: bool,
    /// I/O protocol.
    #[arg(long, value_enum, default_value_t = Protocol::Broadcast)]
    pub protocol: Protocol,
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
    #[arg(long = "udp-wait", value_enum, default_value_t = WaitMode::Blocking)]
    pub udp_wait: WaitMode,
    /// Board firmware of the emulated boards.
    #[arg(long, default_value = "rev8", value_parser = crate::args::firmware())]
    pub firmware: Profile,
    /// Inject a fault half-way (a named preset: its fault script).
    #[arg(long, value_enum, default_value_t = DemoFault::None)]
    pub fault: DemoFault,
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
    #[arg(long, value_parser = crate::args::pacing())]
    pub pacing: Option<Pacing>,
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

/// `firelink` alone: `firelink demo` with every default.
impl Default for DemoArgs {
    fn default() -> Self {
        let command = DemoArgs::augment_args(clap::Command::new("demo"));
        DemoArgs::from_arg_matches(&command.get_matches_from(["demo"]))
            .expect("the demo's defaults parse")
    }
}

/// Show one progress event on stderr (ticks overwrite one line).
pub(crate) fn show(event: &DemoProgress, ticking: &mut bool) {
    if let Some(tick) = tick_line(event) {
        eprint!("\rdemo: {tick}   ");
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
