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
use firelink_testbed::demo::DemoProgress;
use firelink_testbed::demo_request::DemoRequest;
use firelink_testbed::demo_text::{progress_line, tick_line};

use crate::error::CliError;

/// Options of `firelink demo`: the request (the testbed's
/// [`DemoRequest`]), and what the command line does with it.
#[derive(Args, Debug, Clone)]
pub struct DemoArgs {
    /// What to run.
    #[command(flatten)]
    pub request: DemoRequest,
    /// The period as a rate in Hz (the older spelling of --period).
    #[arg(long, hide = true, value_parser = crate::args::servo_rate_hz, conflicts_with_all = ["period", "period_us"])]
    pub rate: Option<ServoPeriod>,
    /// The period in us, 100 to 1000000 (the older spelling of --period).
    #[arg(long = "period-us", hide = true, value_parser = crate::args::servo_period_us, conflicts_with = "period")]
    pub period_us: Option<ServoPeriod>,
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

impl DemoArgs {
    /// Note in the request the options `matches` (this command's) got from
    /// the command line, by argument ID, whatever their value.
    pub fn note_given(&mut self, matches: &clap::ArgMatches) {
        use clap::parser::ValueSource;
        let command = DemoArgs::augment_args(clap::Command::new("demo"));
        self.request.given = command
            .get_arguments()
            .map(|a| a.get_id().as_str())
            .filter(|id| matches.value_source(id) == Some(ValueSource::CommandLine))
            .map(String::from)
            .collect();
    }
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
        say_no_newline!("\rdemo: {tick}   ");
        *ticking = true;
        return;
    }
    if std::mem::take(ticking) {
        say!();
    }
    if let Some(line) = progress_line(event) {
        say!("demo: {line}");
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
        say!("warning: {w}");
    }
    Ok(loaded.config)
}
