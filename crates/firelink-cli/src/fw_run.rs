//! `firelink fw-run [emulate options] -- PROGRAM [ARGS...]`: the emulated
//! boards as /dev/fw* for one unmodified program.
//!
//! The twin's server (`firelink emulate --fw-cdev`) runs on a thread of
//! this process, on a socket in a fresh temporary directory; PROGRAM runs
//! with `libfirelink_fwcdev.so` preloaded (`LD_PRELOAD`, ahead of anything
//! already there) and `FIRELINK_FW_CDEV` naming the socket. When PROGRAM
//! ends the server stops, the directory goes, and `fw-run` exits with
//! PROGRAM's status (128 + the signal's number when a signal ended it).

use std::ffi::OsString;

use clap::Args;

use firelink_testbed::emulation::EmulateRequest;
use firelink_testbed::fw_run::{library_path, run_with_twin};

use crate::error::CliError;

/// Options of `firelink fw-run`.
#[derive(Args, Debug)]
pub struct FwRunArgs {
    /// The boards, their firmware and faults, as `firelink emulate` takes them.
    #[command(flatten)]
    pub emulate: EmulateRequest,
    /// Print the twin server's lines (devices opened, bus resets, its
    /// counters at the end) on stderr.
    #[arg(long)]
    pub verbose: bool,
    /// The program and its arguments (after `--`).
    #[arg(last = true, required = true, value_name = "PROGRAM")]
    pub program: Vec<OsString>,
}

/// `firelink fw-run`: PROGRAM's exit status.
///
/// # Errors
/// The twin could not be built or bound, or PROGRAM not started.
pub fn run(args: &FwRunArgs) -> Result<u8, CliError> {
    let library = library_path()?;
    let (twin, _ids) = args.emulate.twin(&mut |line| say!("{line}"))?;
    let verbose = args.verbose;
    let exit = run_with_twin(twin, &library, &args.program, move |e| {
        if verbose {
            say!("fw-run: {e:?}");
        }
    })?;
    if let Some(problem) = exit.server_problem {
        say!("fw-run: {problem}");
    }
    Ok(exit.status)
}
