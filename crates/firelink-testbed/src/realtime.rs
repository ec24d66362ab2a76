//! Real-time setup for wall-clock pacing: SCHED_FIFO, locked memory and a
//! 1 ns timer slack, each where the OS permits. Failures (EPERM without
//! CAP_SYS_NICE, non-Linux systems) are reported, never fatal.
//!
//! A thread that spins (`--udp-wait spin`) does not take SCHED_FIFO where
//! the kernel throttles real-time threads (`sched_rt_runtime_us` below
//! `sched_rt_period_us`, the default 950 ms of every second): spinning
//! through its waits, it would use up the allowance and be stopped for
//! the rest of each period, 50 ms at a time, longer than the boards'
//! watchdog. It runs at normal priority instead and says why.
//!
//! Used by the command line's demo before its servo loop, and by any
//! other front end that paces a robot on wall-clock time.
//!
//! The OS calls themselves ([`lock_memory`], [`set_fifo`],
//! [`set_timer_slack`], each on any thread of this process by id, 0 for
//! the calling thread) are the tree's one home for them: [`setup`] uses
//! them on the calling thread, the ROS 2 node on the threads a servo point
//! passes through (`firelink_ros2::realtime`).
//!
//! Unsafe code: four libc calls with plain integer arguments and a
//! pointer to a local struct (the crate's other unsafe module is the
//! thread CPU clocks, `cpu.rs`).

use std::io;

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

/// The kernel's real-time throttling: (runtime, period) in us when
/// real-time threads may run only `runtime` of every `period`; `None` when
/// they are not throttled (`sched_rt_runtime_us` is -1 or not below the
/// period) or where the settings cannot be read.
pub fn rt_throttle() -> Option<(u64, u64)> {
    let read = |name: &str| {
        std::fs::read_to_string(format!("/proc/sys/kernel/{name}"))
            .ok()
            .and_then(|t| t.trim().parse::<i64>().ok())
    };
    throttle_of(read("sched_rt_runtime_us")?, read("sched_rt_period_us")?)
}

/// [`rt_throttle`] from the two settings' values.
fn throttle_of(runtime_us: i64, period_us: i64) -> Option<(u64, u64)> {
    let runtime = u64::try_from(runtime_us).ok()?;
    let period = u64::try_from(period_us).ok()?;
    (runtime < period).then_some((runtime, period))
}

/// Why a spinning thread does not take SCHED_FIFO under `throttle`.
fn spin_refusal((runtime, period): (u64, u64)) -> String {
    format!(
        "SCHED_FIFO: not taken with a spinning wait: the kernel lets real-time threads run \
         {runtime} us of every {period} us (/proc/sys/kernel/sched_rt_runtime_us), a spinning \
         one would use that up and stall for the rest, longer than the boards' watchdog \
         (--udp-wait block keeps SCHED_FIFO)"
    )
}

/// Try every setting for the calling thread; `spinning`: the thread spins
/// while it waits (no SCHED_FIFO where real-time threads are throttled).
pub fn setup(priority: i32, spinning: bool) -> RtStatus {
    let mut s = RtStatus::default();
    match rt_throttle().filter(|_| spinning) {
        Some(throttle) => s.errors.push(spin_refusal(throttle)),
        None => match set_fifo(CALLING_THREAD, priority) {
            Ok(()) => s.sched_fifo = Some(priority),
            Err(e) => s.errors.push(format!("SCHED_FIFO: {e}")),
        },
    }
    match lock_memory() {
        Ok(()) => s.memory_locked = true,
        Err(e) => s.errors.push(format!("mlockall: {e}")),
    }
    match set_timer_slack(CALLING_THREAD, 1) {
        Ok(()) => s.timer_slack_1ns = true,
        Err(e) => s.errors.push(format!("timer slack: {e}")),
    }
    s
}

/// The thread id that names the calling thread in [`set_fifo`] and
/// [`set_timer_slack`].
pub const CALLING_THREAD: i32 = 0;

/// Lock the process's memory, now and to come (`mlockall(MCL_CURRENT |
/// MCL_FUTURE)`), so that no page fault stalls a cycle.
///
/// # Errors
/// The OS's refusal (`EPERM` without `CAP_IPC_LOCK` beyond the locked
/// memory limit, `ENOMEM`); `Unsupported` where not Linux.
#[cfg(target_os = "linux")]
#[allow(unsafe_code)]
pub fn lock_memory() -> io::Result<()> {
    // SAFETY: no pointers; the flags are the documented constants.
    match unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) } {
        0 => Ok(()),
        _ => Err(io::Error::last_os_error()),
    }
}

/// Give thread `tid` of this process `SCHED_FIFO` at `priority` (1-99);
/// `tid` [`CALLING_THREAD`] (0) is the calling thread.
///
/// # Errors
/// The OS's refusal (`EPERM` without `CAP_SYS_NICE`, `EINVAL` for a
/// priority out of range, `ESRCH` for no such thread); `Unsupported` where
/// not Linux.
#[cfg(target_os = "linux")]
#[allow(unsafe_code)]
pub fn set_fifo(tid: i32, priority: i32) -> io::Result<()> {
    let param = libc::sched_param {
        sched_priority: priority,
    };
    // SAFETY: `param` is a valid sched_param for the duration of the
    // call; Linux schedules threads and takes a thread id here (0: the
    // calling thread).
    match unsafe { libc::sched_setscheduler(tid, libc::SCHED_FIFO, &param) } {
        0 => Ok(()),
        _ => Err(io::Error::last_os_error()),
    }
}

/// Set thread `tid`'s timer slack to `ns` nanoseconds (0: back to the
/// thread's default); `tid` [`CALLING_THREAD`] (0) is the calling thread
/// (`PR_SET_TIMERSLACK`), any other through `/proc/<tid>/timerslack_ns`.
///
/// # Errors
/// The OS's refusal (writing another thread's slack needs `CAP_SYS_NICE`;
/// `ENOENT` for no such thread); `Unsupported` where not Linux.
#[cfg(target_os = "linux")]
#[allow(unsafe_code)]
pub fn set_timer_slack(tid: i32, ns: u64) -> io::Result<()> {
    if tid != CALLING_THREAD {
        return std::fs::write(timer_slack_file(tid), ns.to_string());
    }
    let ns = libc::c_ulong::try_from(ns).map_err(|_| {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("timer slack {ns} ns does not fit this system's unsigned long"),
        )
    })?;
    // SAFETY: PR_SET_TIMERSLACK takes one unsigned long argument.
    match unsafe { libc::prctl(libc::PR_SET_TIMERSLACK, ns) } {
        0 => Ok(()),
        _ => Err(io::Error::last_os_error()),
    }
}

/// Thread `tid`'s timer slack, ns, as the kernel has it now (`None`: not
/// readable, or not Linux).
pub fn timer_slack_ns(tid: i32) -> Option<u64> {
    if !cfg!(target_os = "linux") {
        return None;
    }
    std::fs::read_to_string(timer_slack_file(tid))
        .ok()?
        .trim()
        .parse()
        .ok()
}

/// Where Linux shows thread `tid`'s timer slack: `/proc/<tid>`, which
/// names one thread (the file is not under `/proc/self/task/<tid>` nor
/// `/proc/thread-self`); [`CALLING_THREAD`] by its own id.
fn timer_slack_file(tid: i32) -> String {
    let tid = if tid == CALLING_THREAD {
        current_tid()
    } else {
        tid
    };
    format!("/proc/{tid}/timerslack_ns")
}

/// The calling thread's id (`gettid`), as [`set_fifo`] and
/// [`set_timer_slack`] take it; 0 ([`CALLING_THREAD`]) where not Linux.
#[cfg(target_os = "linux")]
#[allow(unsafe_code)]
pub fn current_tid() -> i32 {
    // SAFETY: gettid takes no arguments and cannot fail.
    unsafe { libc::gettid() }
}

/// Not Linux: refused as unsupported.
#[cfg(not(target_os = "linux"))]
pub fn lock_memory() -> io::Result<()> {
    Err(unsupported())
}

/// Not Linux: refused as unsupported.
#[cfg(not(target_os = "linux"))]
pub fn set_fifo(_tid: i32, _priority: i32) -> io::Result<()> {
    Err(unsupported())
}

/// Not Linux: refused as unsupported.
#[cfg(not(target_os = "linux"))]
pub fn set_timer_slack(_tid: i32, _ns: u64) -> io::Result<()> {
    Err(unsupported())
}

/// Not Linux: no thread ids; the calling thread.
#[cfg(not(target_os = "linux"))]
pub fn current_tid() -> i32 {
    CALLING_THREAD
}

#[cfg(not(target_os = "linux"))]
fn unsupported() -> io::Error {
    io::Error::new(
        io::ErrorKind::Unsupported,
        "real-time settings are implemented for Linux only",
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn throttling_is_read_from_the_two_settings() {
        // The kernel's default: 950 ms of every second.
        assert_eq!(throttle_of(950_000, 1_000_000), Some((950_000, 1_000_000)));
        // -1: real-time threads are never throttled; nor with the whole
        // period allowed.
        assert_eq!(throttle_of(-1, 1_000_000), None);
        assert_eq!(throttle_of(1_000_000, 1_000_000), None);
        assert_eq!(throttle_of(950_000, -5), None);
    }

    /// Timer slack needs no privilege on one's own thread: set through
    /// either path (0 and the thread's own id), it reads back.
    #[cfg(target_os = "linux")]
    #[test]
    fn the_timer_slack_is_set_on_the_calling_thread_by_0_or_by_its_id() {
        std::thread::spawn(|| {
            let tid = current_tid();
            assert!(tid > 0);
            set_timer_slack(CALLING_THREAD, 1).unwrap();
            assert_eq!(timer_slack_ns(tid), Some(1));
            assert_eq!(timer_slack_ns(CALLING_THREAD), Some(1));
            set_timer_slack(tid, 7).unwrap();
            assert_eq!(timer_slack_ns(CALLING_THREAD), Some(7));
        })
        .join()
        .unwrap();
    }

    /// Refusals come back as the OS's errors, named by kind.
    #[cfg(target_os = "linux")]
    #[test]
    fn refusals_are_errors_of_their_kind() {
        // No thread of that id (pid_max is at most 2^22).
        let missing = i32::MAX;
        assert!(set_timer_slack(missing, 1).is_err());
        assert_eq!(timer_slack_ns(missing), None);
        // Priority 0 is not a SCHED_FIFO priority, privileged or not.
        let invalid = set_fifo(CALLING_THREAD, 0).unwrap_err();
        assert_eq!(invalid.kind(), io::ErrorKind::InvalidInput, "{invalid}");
    }

    #[test]
    fn a_spinning_thread_is_told_why_it_has_no_sched_fifo() {
        let why = spin_refusal((950_000, 1_000_000));
        assert!(why.contains("950000 us of every 1000000 us"), "{why}");
        assert!(why.contains("--udp-wait block"), "{why}");
    }
}
