//! Stop requests: how a program that powered a robot learns that it must
//! end (Ctrl-C, `kill`, a closed terminal, a supervisor stopping it, a
//! Python `KeyboardInterrupt`), so that it powers the robot down before it
//! does.
//!
//! A [`StopRequest`] is a shared flag that remembers *why* (the signal
//! number, or [`StopRequest::BY_CALLER`]). Loops that run a robot check it
//! between cycles (an atomic load: no allocation, no lock); the power-down
//! itself is [`RobotIo::power_down`](crate::RobotIo::power_down), which the
//! I/O systems also run when they are dropped.
//!
//! [`install_signal_handlers`] points SIGINT, SIGTERM and SIGHUP at the
//! process's own request ([`StopRequest::process`]). The first signal asks
//! for an orderly stop; a second one of any of them ends the process at
//! once (the boards' watchdogs then turn the amplifiers off), so a program
//! stuck in a time-out can still be stopped. A server that powers
//! nothing stops on SIGINT, SIGTERM or a deadline ([`server_stop_flag`]).

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, OnceLock};

/// A request to stop, shared between whoever asks and the loop that obeys.
#[derive(Debug, Clone, Default)]
pub struct StopRequest(Arc<AtomicUsize>);

/// Why a stop was requested.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopReason {
    /// A signal (SIGINT, SIGTERM, SIGHUP).
    Signal(i32),
    /// The program itself (e.g. Python's `KeyboardInterrupt`, a test).
    Caller,
}

impl StopReason {
    /// The conventional exit status of a program that ends for this reason
    /// (128 + the signal's number; 130 for a caller's interrupt).
    pub fn exit_status(self) -> i32 {
        match self {
            StopReason::Signal(s) => 128 + s,
            StopReason::Caller => 130,
        }
    }
}

impl core::fmt::Display for StopReason {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            StopReason::Signal(s) => match *s {
                libc_consts::SIGINT => f.write_str("SIGINT (Ctrl-C)"),
                libc_consts::SIGTERM => f.write_str("SIGTERM"),
                libc_consts::SIGHUP => f.write_str("SIGHUP (terminal closed)"),
                other => write!(f, "signal {other}"),
            },
            StopReason::Caller => f.write_str("a stop request"),
        }
    }
}

/// The signal numbers this module names (Linux and every Unix Firelink runs
/// on agree on these three).
mod libc_consts {
    pub const SIGHUP: i32 = 1;
    pub const SIGINT: i32 = 2;
    pub const SIGTERM: i32 = 15;
}

impl StopRequest {
    /// The value a caller's own request stores (no signal has number 0).
    pub const BY_CALLER: usize = usize::MAX;

    /// A fresh request, not set.
    pub fn new() -> StopRequest {
        StopRequest::default()
    }

    /// The process's own request: the one [`install_signal_handlers`] sets.
    /// Every robot loop watches it unless given another.
    pub fn process() -> StopRequest {
        static PROCESS: OnceLock<StopRequest> = OnceLock::new();
        PROCESS.get_or_init(StopRequest::new).clone()
    }

    /// Ask the loop to stop (keeps the first reason).
    pub fn request(&self) {
        let _ = self
            .0
            .compare_exchange(0, Self::BY_CALLER, Ordering::SeqCst, Ordering::SeqCst);
    }

    /// Whether a stop was asked for.
    #[inline]
    pub fn is_requested(&self) -> bool {
        self.0.load(Ordering::Relaxed) != 0
    }

    /// Why, if a stop was asked for.
    pub fn reason(&self) -> Option<StopReason> {
        match self.0.load(Ordering::SeqCst) {
            0 => None,
            Self::BY_CALLER => Some(StopReason::Caller),
            s => Some(StopReason::Signal(i32::try_from(s).unwrap_or(0))),
        }
    }

    /// Whether `other` is this same request.
    pub fn same_as(&self, other: &StopRequest) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }
}

/// Point SIGINT, SIGTERM and SIGHUP at [`StopRequest::process`]: the first
/// asks for an orderly stop (the loop powers the robot down and returns),
/// a second ends the process at once. Returns the process's request.
/// Idempotent.
///
/// # Errors
/// The handlers could not be installed.
pub fn install_signal_handlers() -> std::io::Result<StopRequest> {
    static INSTALLED: OnceLock<()> = OnceLock::new();
    let stop = StopRequest::process();
    if INSTALLED.get().is_none() {
        use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
        // Set by the first of these signals; the second finds it set.
        let seen = Arc::new(std::sync::atomic::AtomicBool::new(false));
        for signal in [SIGINT, SIGTERM, SIGHUP] {
            // Registered first, so it runs first: after an earlier signal,
            // exit at once.
            signal_hook::flag::register_conditional_shutdown(
                signal,
                128 + signal,
                Arc::clone(&seen),
            )?;
            signal_hook::flag::register(signal, Arc::clone(&seen))?;
            let flag = Arc::clone(&stop.0);
            signal_hook::flag::register_usize(signal, flag, signal as usize)?;
        }
        let _ = INSTALLED.set(());
    }
    Ok(stop)
}

/// The stop of a server that powers nothing (an emulator): a flag set by
/// SIGINT or SIGTERM, or when `deadline` has passed, if one is given.
///
/// # Errors
/// A signal handler could not be installed.
pub fn server_stop_flag(
    deadline: Option<std::time::Duration>,
) -> std::io::Result<Arc<std::sync::atomic::AtomicBool>> {
    let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
    signal_hook::flag::register(signal_hook::consts::SIGINT, Arc::clone(&stop))?;
    signal_hook::flag::register(signal_hook::consts::SIGTERM, Arc::clone(&stop))?;
    if let Some(deadline) = deadline {
        let stop = Arc::clone(&stop);
        std::thread::spawn(move || {
            std::thread::sleep(deadline);
            stop.store(true, Ordering::Relaxed);
        });
    }
    Ok(stop)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_request_keeps_its_first_reason() {
        let s = StopRequest::new();
        assert!(!s.is_requested());
        assert_eq!(s.reason(), None);
        let same = s.clone();
        same.request();
        assert!(s.is_requested());
        assert_eq!(s.reason(), Some(StopReason::Caller));
        assert!(s.same_as(&same));
        assert!(!s.same_as(&StopRequest::new()));
        assert_eq!(StopReason::Signal(15).exit_status(), 143);
        assert_eq!(StopReason::Signal(15).to_string(), "SIGTERM");
    }
}
