//! `firelink soak`: the fault soak and the watchdog proof
//! ([`firelink_testbed::dvrk::soak`], [`firelink_testbed::dvrk::watchdog`]; the
//! options are the testbed's [`SoakRequest`]).

use std::io::Write;

use clap::Args;

use firelink_testbed::dvrk::soak::SoakRequest;

use crate::error::CliError;

/// Options of `firelink soak`.
#[derive(Args, Debug)]
pub struct SoakArgs {
    /// What to run.
    #[command(flatten)]
    pub request: SoakRequest,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Run `firelink soak`; exits non-zero when a fault went unaccounted for
/// or a safety invariant broke.
pub fn run(args: &SoakArgs, out: &mut impl Write) -> Result<(), CliError> {
    let quiet = crate::args::quiet();
    let outcome = args.request.run(&mut |line| {
        if !quiet {
            say!("soak: {line}");
        }
    })?;
    if args.json {
        writeln!(out, "{}", outcome.json()?)?;
    } else {
        write!(out, "{outcome}")?;
    }
    outcome.verdict().map_err(CliError::Failed)
}
