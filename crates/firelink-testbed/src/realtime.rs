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
//! Unsafe code: three libc calls with plain integer arguments and a
//! pointer to a local struct (the crate's other unsafe module is the
//! thread CPU clocks, `cpu.rs`).

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
#[cfg(target_os = "linux")]
#[allow(unsafe_code)]
pub fn setup(priority: i32, spinning: bool) -> RtStatus {
    let mut s = RtStatus::default();
    let err = || std::io::Error::last_os_error().to_string();
    let param = libc::sched_param {
        sched_priority: priority,
    };
    match rt_throttle().filter(|_| spinning) {
        Some(throttle) => s.errors.push(spin_refusal(throttle)),
        // SAFETY: `param` is a valid sched_param for the duration of the
        // call; pid 0 is the calling thread.
        None if unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) } == 0 => {
            s.sched_fifo = Some(priority);
        }
        None => s.errors.push(format!("SCHED_FIFO: {}", err())),
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
pub fn setup(_priority: i32, _spinning: bool) -> RtStatus {
    RtStatus {
        errors: vec!["real-time settings are only implemented for Linux".into()],
        ..RtStatus::default()
    }
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

    #[test]
    fn a_spinning_thread_is_told_why_it_has_no_sched_fifo() {
        let why = spin_refusal((950_000, 1_000_000));
        assert!(why.contains("950000 us of every 1000000 us"), "{why}");
        assert!(why.contains("--udp-wait block"), "{why}");
    }
}
