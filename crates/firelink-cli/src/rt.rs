//! Real-time setup for wall-clock pacing: SCHED_FIFO, locked memory and a
//! 1 ns timer slack, each where the OS permits. Failures (EPERM without
//! CAP_SYS_NICE, non-Linux systems) are reported, never fatal.
//!
//! The only unsafe code of the workspace: three libc calls with plain
//! integer arguments and a pointer to a local struct.

/// What took effect.
#[derive(Debug, Clone, Default)]
pub struct RtStatus {
    /// SCHED_FIFO at this priority.
    pub sched_fifo: Option<i32>,
    /// mlockall(MCL_CURRENT | MCL_FUTURE) succeeded.
    pub memory_locked: bool,
    /// Timer slack set to 1 ns.
    pub timer_slack_1ns: bool,
    /// Why the others did not.
    pub errors: Vec<String>,
}

/// Try every setting for the calling thread.
#[cfg(target_os = "linux")]
#[allow(unsafe_code)]
pub fn setup(priority: i32) -> RtStatus {
    let mut s = RtStatus::default();
    let err = || std::io::Error::last_os_error().to_string();
    let param = libc::sched_param {
        sched_priority: priority,
    };
    // SAFETY: `param` is a valid sched_param for the duration of the call;
    // pid 0 is the calling thread.
    if unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) } == 0 {
        s.sched_fifo = Some(priority);
    } else {
        s.errors.push(format!("SCHED_FIFO: {}", err()));
    }
    // SAFETY: no pointers; flags are the documented constants.
    if unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) } == 0 {
        s.memory_locked = true;
    } else {
        s.errors.push(format!("mlockall: {}", err()));
    }
    // SAFETY: PR_SET_TIMERSLACK takes one unsigned long argument.
    if unsafe { libc::prctl(libc::PR_SET_TIMERSLACK, 1 as libc::c_ulong) } == 0 {
        s.timer_slack_1ns = true;
    } else {
        s.errors.push(format!("timer slack: {}", err()));
    }
    s
}

/// Not Linux: nothing to do.
#[cfg(not(target_os = "linux"))]
pub fn setup(_priority: i32) -> RtStatus {
    RtStatus {
        errors: vec!["real-time settings are only implemented for Linux".into()],
        ..RtStatus::default()
    }
}
