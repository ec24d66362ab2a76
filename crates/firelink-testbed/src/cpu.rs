//! CPU time of one thread, for the benchmark's figures: the calling
//! thread's (the host's I/O), or another thread's read from outside while
//! it runs (the in-process emulator's server thread, sampled between
//! blocks of cycles without touching its loop).
//!
//! Linux: `pthread_getcpuclockid` names the thread's CPU-time clock (the
//! clock `CLOCK_THREAD_CPUTIME_ID` is inside the thread) and
//! `clock_gettime` reads it. Elsewhere no clock is available and the
//! figures are absent. Unsafe code: two libc calls with plain arguments,
//! in the two functions at the end (the crate's other unsafe module is
//! the real-time setup, `realtime.rs`).

use std::thread::JoinHandle;
use std::time::Duration;

/// A thread's CPU-time clock: user and system time the thread has used.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ThreadCpuClock {
    #[cfg(target_os = "linux")]
    id: libc::clockid_t,
}

impl ThreadCpuClock {
    /// The calling thread's clock (readable from any thread while this one
    /// runs).
    pub fn current() -> Option<ThreadCpuClock> {
        #[cfg(target_os = "linux")]
        {
            linux::clock_of(linux::this_thread()).map(|id| ThreadCpuClock { id })
        }
        #[cfg(not(target_os = "linux"))]
        {
            None
        }
    }

    /// The clock of the thread behind `handle`. Read it only while that
    /// thread runs: once it has ended the clock reads nothing.
    pub fn of<T>(handle: &JoinHandle<T>) -> Option<ThreadCpuClock> {
        #[cfg(target_os = "linux")]
        {
            use std::os::unix::thread::JoinHandleExt;
            if handle.is_finished() {
                return None;
            }
            linux::clock_of(handle.as_pthread_t()).map(|id| ThreadCpuClock { id })
        }
        #[cfg(not(target_os = "linux"))]
        {
            let _ = handle;
            None
        }
    }

    /// CPU time the thread has used so far, or `None` when the clock
    /// cannot be read (the thread has ended).
    pub fn now(&self) -> Option<Duration> {
        #[cfg(target_os = "linux")]
        {
            linux::read(self.id)
        }
        #[cfg(not(target_os = "linux"))]
        {
            None
        }
    }
}

impl ThreadCpuClock {
    /// [`now`](Self::now), for the clock of the thread behind `thread`
    /// (see [`of`](Self::of)), read only while that thread runs: `None`
    /// once it has ended or been joined (`thread` is `None`).
    pub fn now_while_running<T>(&self, thread: Option<&JoinHandle<T>>) -> Option<Duration> {
        thread
            .is_some_and(|t| !t.is_finished())
            .then(|| self.now())
            .flatten()
    }
}

#[cfg(target_os = "linux")]
mod linux {
    use std::time::Duration;

    /// The calling thread.
    #[allow(unsafe_code)]
    pub(super) fn this_thread() -> libc::pthread_t {
        // SAFETY: pthread_self takes nothing and cannot fail.
        unsafe { libc::pthread_self() }
    }

    /// The CPU-time clock of `thread`, which must not have been joined
    /// (callers pass the calling thread or an unjoined handle's thread).
    #[allow(unsafe_code)]
    pub(super) fn clock_of(thread: libc::pthread_t) -> Option<libc::clockid_t> {
        let mut id: libc::clockid_t = 0;
        // SAFETY: `thread` names a live or unjoined thread (see above) and
        // `id` is a valid place for the one value the call writes.
        let rc = unsafe { libc::pthread_getcpuclockid(thread, &mut id) };
        (rc == 0).then_some(id)
    }

    /// Read clock `id`.
    #[allow(unsafe_code)]
    pub(super) fn read(id: libc::clockid_t) -> Option<Duration> {
        let mut ts = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: `ts` is a valid timespec the call only writes; an
        // invalid clock is an error return, not undefined behaviour.
        let rc = unsafe { libc::clock_gettime(id, &mut ts) };
        if rc != 0 {
            return None;
        }
        let secs = u64::try_from(ts.tv_sec).ok()?;
        let nanos = u32::try_from(ts.tv_nsec).ok()?;
        Some(Duration::new(secs, 0) + Duration::from_nanos(u64::from(nanos)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A thread's clock counts its work; another thread's clock is read
    /// from outside while it runs, and not taken once it has ended.
    #[test]
    #[cfg(target_os = "linux")]
    fn thread_clocks_count_their_own_thread() {
        let me = ThreadCpuClock::current().unwrap();
        let before = me.now().unwrap();
        let mut x = 0u64;
        for i in 0..2_000_000u64 {
            x = std::hint::black_box(x.wrapping_mul(31).wrapping_add(i));
        }
        assert!(me.now().unwrap() > before, "{x}");

        let (tx, rx) = std::sync::mpsc::channel::<()>();
        let idle = std::thread::spawn(move || {
            let _ = rx.recv();
        });
        let clock = ThreadCpuClock::of(&idle).unwrap();
        assert!(clock.now().is_some());
        assert!(clock.now_while_running(Some(&idle)).is_some());
        assert_ne!(clock, me);
        drop(tx);
        while !idle.is_finished() {
            std::thread::yield_now();
        }
        assert_eq!(ThreadCpuClock::of(&idle), None);
        assert_eq!(clock.now_while_running(Some(&idle)), None, "ended");
        idle.join().unwrap();
        assert_eq!(clock.now_while_running::<()>(None), None, "joined");
    }
}
