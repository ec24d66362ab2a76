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
use std::io::Write;
use std::os::unix::process::ExitStatusExt;
use std::path::PathBuf;
use std::process::Command;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use clap::Args;

use crate::emulate_cmd::{EmulateArgs, build_twin};
use crate::error::CliError;
use firelink_emulate::fw_cdev;

/// The environment variable naming the twin's socket (read by the
/// preloaded library).
pub const SOCKET_ENV: &str = "FIRELINK_FW_CDEV";
/// Where the preloaded library is, when not next to this binary.
pub const LIBRARY_ENV: &str = "FIRELINK_FWCDEV_LIB";
/// The preloaded library's file name.
const LIBRARY: &str = "libfirelink_fwcdev.so";

/// Options of `firelink fw-run`.
#[derive(Args, Debug)]
pub struct FwRunArgs {
    /// The boards, their firmware and faults, as `firelink emulate` takes them.
    #[command(flatten)]
    pub emulate: EmulateArgs,
    /// Print the twin server's lines (devices opened, bus resets, its
    /// counters at the end) on stderr.
    #[arg(long)]
    pub verbose: bool,
    /// The program and its arguments (after `--`).
    #[arg(last = true, required = true, value_name = "PROGRAM")]
    pub program: Vec<OsString>,
}

/// The preloaded library: `$FIRELINK_FWCDEV_LIB`, or next to this binary
/// (where `cargo build` puts both).
///
/// # Errors
/// [`CliError::TwinLibraryMissing`] naming where it was looked for.
pub fn library_path() -> Result<PathBuf, CliError> {
    if let Some(p) = std::env::var_os(LIBRARY_ENV) {
        return Ok(PathBuf::from(p));
    }
    let here = std::env::current_exe()?;
    let beside = here.with_file_name(LIBRARY);
    if beside.exists() {
        return Ok(beside);
    }
    Err(CliError::TwinLibraryMissing {
        path: beside.display().to_string(),
    })
}

/// `firelink fw-run`: PROGRAM's exit status.
///
/// # Errors
/// The twin could not be built or bound, or PROGRAM not started.
pub fn run(args: &FwRunArgs) -> Result<u8, CliError> {
    let library = library_path()?;
    let (mut twin, _ids) = build_twin(&args.emulate)?;
    let dir = temp_dir()?;
    let socket = dir.join("fw-cdev.sock");
    let listener = fw_cdev::bind(&socket)?;
    let stop = Arc::new(AtomicBool::new(false));
    let verbose = args.verbose;
    let server = {
        let stop = Arc::clone(&stop);
        std::thread::spawn(move || {
            let mut err = std::io::stderr();
            let log = |e: fw_cdev::ServeEvent| {
                if verbose {
                    let _ = writeln!(err, "fw-run: {e:?}");
                }
            };
            fw_cdev::serve(&mut twin, &listener, &stop, log)
        })
    };
    let mut preload = library.into_os_string();
    if let Some(old) = std::env::var_os("LD_PRELOAD").filter(|o| !o.is_empty()) {
        preload.push(" ");
        preload.push(old);
    }
    let (program, rest) = args
        .program
        .split_first()
        .ok_or(CliError::Failed("fw-run: no program given".into()))?;
    let status = Command::new(program)
        .args(rest)
        .env("LD_PRELOAD", &preload)
        .env(SOCKET_ENV, &socket)
        .status();
    stop.store(true, Ordering::Relaxed);
    let served = server.join();
    let _ = std::fs::remove_file(&socket);
    let _ = std::fs::remove_dir(&dir);
    let status = status.map_err(|e| {
        CliError::Io(std::io::Error::new(
            e.kind(),
            format!("cannot run {}: {e}", program.to_string_lossy()),
        ))
    })?;
    match served {
        Ok(Ok(())) => {}
        Ok(Err(e)) => eprintln!("fw-run: the twin's server failed: {e}"),
        Err(_) => eprintln!("fw-run: the twin's server panicked"),
    }
    Ok(match (status.code(), status.signal()) {
        (Some(code), _) => u8::try_from(code).unwrap_or(1),
        (None, Some(signal)) => u8::try_from(128 + signal).unwrap_or(1),
        _ => 1,
    })
}

/// A new private directory for the socket.
pub(crate) fn temp_dir() -> Result<PathBuf, CliError> {
    let base = std::env::temp_dir();
    for n in 0..1000u32 {
        let dir = base.join(format!("firelink-fw-{}-{n}", std::process::id()));
        match std::fs::create_dir(&dir) {
            Ok(()) => return Ok(dir),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e.into()),
        }
    }
    Err(CliError::Io(std::io::Error::other(
        "no free temporary directory for the twin's socket",
    )))
}
