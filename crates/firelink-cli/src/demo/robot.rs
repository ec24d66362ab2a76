//! `firelink demo`: the options as one [`DemoRequest`] (the testbed picks
//! the robot and runs it), its progress on stderr, and the report printed.

use std::io::Write;

use firelink_host::udp::WaitMode;
use firelink_testbed::demo::RealtimeStatus;
use firelink_testbed::demo_request::{DemoConfig, DemoRequest};
use firelink_testbed::mahru::MahruConfig;
use firelink_testbed::rig::RobotKind;

use super::{DemoArgs, load_config, show};
use crate::error::CliError;

/// The request the options make; the configuration file is loaded (its
/// warnings printed) as the robot reads it.
///
/// # Errors
/// The configuration could not be loaded.
pub fn request(args: &DemoArgs) -> Result<DemoRequest, CliError> {
    let request = &args.request;
    let config = match (&args.config, request.robot) {
        (None, _) => DemoConfig::Builtin,
        // Not read: the session refuses --config (it is in `given`).
        (Some(_), _) if args.teleop => DemoConfig::Builtin,
        (Some(path), RobotKind::Mahru) => DemoConfig::Mahru(MahruConfig::load(path)?),
        (Some(path), _) => DemoConfig::Io(load_config(path)?),
    };
    let mut given = request.given.clone();
    if args.config.is_some() && !given.iter().any(|g| g == "config") {
        given.push("config".into());
    }
    Ok(DemoRequest {
        config,
        given,
        teleop: args.teleop,
        period: request.period.or(args.rate).or(args.period_us),
        ..request.clone()
    })
}

/// Run `firelink demo`: progress on stderr unless quiet, the report on
/// `out` (JSON with `--json`, else the table); a run that did not do what
/// it was asked exits 3.
pub fn run(args: &DemoArgs, out: &mut impl Write) -> Result<(), CliError> {
    let request = request(args)?;
    let quiet = args.quiet || crate::args::quiet();
    if let Some(w) = request.watchdog.warning() {
        say!("demo: {w}");
    }
    // The port's reads spin over UDP with `--udp-wait spin`.
    let spinning = request.udp_wait == WaitMode::Spinning && !request.port.is_sim();
    let setup = move || RealtimeStatus::take(80, spinning);
    let setup: &dyn Fn() -> RealtimeStatus = &setup;
    let mut ticking = false;
    let outcome = request.run(
        (!args.no_rt).then_some(setup),
        &mut |event| {
            if !quiet {
                show(&event, &mut ticking);
            }
        },
        &mut |line| {
            if !quiet {
                say!("demo: {line}");
            }
        },
    )?;
    if ticking {
        say!();
    }
    if let Some(line) = outcome.realtime_line().filter(|_| !quiet) {
        say!("demo: {line}");
    }
    if args.json {
        writeln!(out, "{}", outcome.json()?)?;
    } else {
        write!(out, "{}", outcome.table())?;
    }
    outcome.verdict().map_err(CliError::Failed)
}
