//! One unmodified program with the emulated boards as its /dev/fw*
//! devices (`firelink fw-run`, and the benchmark's `fw` points): the
//! twin's server on a thread of this process, on a socket in a fresh
//! temporary directory; the program run with `libfirelink_fwcdev.so`
//! preloaded (`LD_PRELOAD`, ahead of anything already there) and
//! [`SOCKET_ENV`] naming the socket. When the program ends the server
//! stops and the directory goes.

use std::ffi::OsString;
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use firelink_emulate::fw_cdev::{self, ServeEvent, Twin};

/// The environment variable naming the twin's socket (the preloaded
/// library connects there; the server binds it: `fw-run`'s, the
/// benchmark's).
pub const SOCKET_ENV: &str = "FIRELINK_FW_CDEV";

/// Where the preloaded library is, when not next to the running binary.
pub const LIBRARY_ENV: &str = "FIRELINK_FWCDEV_LIB";
/// The preloaded library's file name.
const LIBRARY: &str = "libfirelink_fwcdev.so";

/// The preloaded library is not built.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "the /dev/fw* twin library is not built: run `cargo build -p firelink-fwcdev` or set FIRELINK_FWCDEV_LIB (looked for {path})"
)]
pub struct TwinLibraryMissing {
    /// Where it was looked for.
    pub path: String,
}

/// The preloaded library: `$FIRELINK_FWCDEV_LIB`, or next to the running
/// binary (where `cargo build` puts both).
///
/// # Errors
/// [`TwinLibraryMissing`] naming where it was looked for.
pub fn library_path() -> Result<PathBuf, TwinLibraryMissing> {
    if let Some(p) = std::env::var_os(LIBRARY_ENV) {
        return Ok(PathBuf::from(p));
    }
    let beside = std::env::current_exe()
        .map(|here| here.with_file_name(LIBRARY))
        .unwrap_or_else(|_| PathBuf::from(LIBRARY));
    if beside.exists() {
        return Ok(beside);
    }
    Err(TwinLibraryMissing {
        path: beside.display().to_string(),
    })
}

/// `LD_PRELOAD` with `library` ahead of what is already there.
pub fn preload(library: &Path) -> OsString {
    let mut preload = library.as_os_str().to_os_string();
    if let Some(old) = std::env::var_os("LD_PRELOAD").filter(|o| !o.is_empty()) {
        preload.push(" ");
        preload.push(old);
    }
    preload
}

/// A new private directory for the twin's socket.
///
/// # Errors
/// It could not be made.
pub fn temp_dir() -> std::io::Result<PathBuf> {
    let base = std::env::temp_dir();
    for n in 0..1000u32 {
        let dir = base.join(format!("firelink-fw-{}-{n}", std::process::id()));
        match std::fs::create_dir(&dir) {
            Ok(()) => return Ok(dir),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
    Err(std::io::Error::other(
        "no free temporary directory for the twin's socket",
    ))
}

/// Set in the process [`rerun_with_twin`] starts.
pub const UNDER_TWIN_ENV: &str = "FIRELINK_BENCH_UNDER_TWIN";

/// Whether this process is one [`rerun_with_twin`] started.
pub fn under_twin() -> bool {
    std::env::var_os(UNDER_TWIN_ENV).is_some()
}

/// Run this executable again with `args`, the twin library `library`
/// preloaded, a fresh socket path for a twin server of its own
/// ([`SOCKET_ENV`]) and [`UNDER_TWIN_ENV`] set: for a command whose
/// `FirewirePort` needs the library in its own process, which only the
/// loader can put there. Its stderr passes through; its stdout and status
/// are returned.
///
/// # Errors
/// No temporary directory, or the executable could not be started.
pub fn rerun_with_twin(
    library: &Path,
    args: impl IntoIterator<Item = OsString>,
) -> std::io::Result<std::process::Output> {
    let dir = temp_dir()?;
    let output = Command::new(std::env::current_exe()?)
        .args(args)
        .env("LD_PRELOAD", preload(library))
        .env(SOCKET_ENV, dir.join("fw-cdev.sock"))
        .env(UNDER_TWIN_ENV, "1")
        .stderr(std::process::Stdio::inherit())
        .output();
    let _ = std::fs::remove_dir_all(&dir);
    output
}

/// How the program ended, and whether the twin's server did well.
#[derive(Debug)]
pub struct FwRunExit {
    /// The program's exit status; 128 + the signal's number when a
    /// signal ended it.
    pub status: u8,
    /// What went wrong with the twin's server, if anything.
    pub server_problem: Option<String>,
}

/// The status a shell reports for `status`.
fn shell_status(status: ExitStatus) -> u8 {
    match (status.code(), status.signal()) {
        (Some(code), _) => u8::try_from(code).unwrap_or(1),
        (None, Some(signal)) => u8::try_from(128 + signal).unwrap_or(1),
        _ => 1,
    }
}

/// Run `program` (its name, then its arguments) with `twin` served as
/// /dev/fw* through `library` preloaded; `on_event` sees the server's
/// events (on its thread).
///
/// # Errors
/// The socket could not be made or bound, or the program not started
/// (naming it).
pub fn run_with_twin(
    mut twin: Twin,
    library: &Path,
    program: &[OsString],
    on_event: impl FnMut(ServeEvent) + Send + 'static,
) -> std::io::Result<FwRunExit> {
    let (name, rest) = program.split_first().ok_or_else(|| {
        std::io::Error::new(std::io::ErrorKind::InvalidInput, "fw-run: no program given")
    })?;
    let dir = temp_dir()?;
    let socket = dir.join("fw-cdev.sock");
    let listener = fw_cdev::bind(&socket)?;
    let stop = Arc::new(AtomicBool::new(false));
    let server = {
        let stop = Arc::clone(&stop);
        std::thread::spawn(move || fw_cdev::serve(&mut twin, &listener, &stop, on_event))
    };
    let status = Command::new(name)
        .args(rest)
        .env("LD_PRELOAD", preload(library))
        .env(SOCKET_ENV, &socket)
        .status();
    stop.store(true, Ordering::Relaxed);
    let served = server.join();
    let _ = std::fs::remove_file(&socket);
    let _ = std::fs::remove_dir(&dir);
    let status = status.map_err(|e| {
        std::io::Error::new(
            e.kind(),
            format!("cannot run {}: {e}", name.to_string_lossy()),
        )
    })?;
    let server_problem = match served {
        Ok(Ok(())) => None,
        Ok(Err(e)) => Some(format!("the twin's server failed: {e}")),
        Err(_) => Some("the twin's server panicked".to_string()),
    };
    Ok(FwRunExit {
        status: shell_status(status),
        server_problem,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_signal_reads_as_128_plus_its_number() {
        assert_eq!(shell_status(ExitStatus::from_raw(3 << 8)), 3);
        // Killed by SIGTERM (15).
        assert_eq!(shell_status(ExitStatus::from_raw(15)), 143);
    }

    #[test]
    fn temporary_directories_are_new_each_time() {
        let a = temp_dir().unwrap();
        let b = temp_dir().unwrap();
        assert_ne!(a, b);
        std::fs::remove_dir(&a).unwrap();
        std::fs::remove_dir(&b).unwrap();
    }
}
