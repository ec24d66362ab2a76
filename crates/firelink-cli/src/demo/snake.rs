//! `firelink demo --robot snake`: seed 001's 36-axis system on its own
//! 7-channel nodes, servoed through the abstract robot I/O. The run is
//! [`firelink_testbed::snake::demo`]; this file maps the demo's options
//! onto it and prints the report.

use std::io::Write;

use firelink_control::config::{IoConfig, presets};
use firelink_control::runner::Pacing;
use firelink_testbed::snake::demo::{SnakeDemoOptions, run_snake_demo};
use firelink_testbed::snake::is_snake_config;

use super::{DemoArgs, DemoRobot, load_config, print_report, with_progress};
use crate::error::CliError;

fn config(args: &DemoArgs) -> Result<Option<IoConfig>, CliError> {
    args.config
        .as_ref()
        .map(|path| load_config(path))
        .transpose()
}

/// Whether the options ask for the Snake robot (`--robot snake`, or a
/// `--config` on SNAKE nodes).
pub fn wanted(args: &DemoArgs) -> Result<bool, CliError> {
    if args.robot == DemoRobot::Snake {
        return Ok(true);
    }
    Ok(config(args)?.as_ref().is_some_and(is_snake_config))
}

/// The Snake demo's options from the command line.
pub fn options(args: &DemoArgs) -> Result<SnakeDemoOptions, CliError> {
    let config = config(args)?.unwrap_or_else(presets::snake_seed001);
    let watchdog = args.watchdog;
    Ok(SnakeDemoOptions {
        config,
        rate_hz: args.rate.unwrap_or(1000.0),
        duration_s: args.duration,
        port: args.port,
        fault: args.fault.into(),
        faults: args.faults.clone(),
        pacing: args.pacing.map(Pacing::from),
        watchdog,
        find_max_rate: !args.no_rate_search,
        udp_wait: args.udp_wait.into(),
        ..SnakeDemoOptions::default()
    })
}

/// Run `firelink demo --robot snake`.
pub fn run(args: &DemoArgs, out: &mut impl Write) -> Result<(), CliError> {
    let options = options(args)?;
    let report = with_progress(args, |rt, progress| run_snake_demo(&options, rt, progress))?;
    print_report(args, out, &report)?;
    report.verdict().map_err(CliError::Failed)
}
