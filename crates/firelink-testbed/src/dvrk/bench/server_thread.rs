//! A benchmark's server on a thread of its own (the UDP floor's
//! responder, the fw points' twin server): started with a stop flag, its
//! CPU time readable while it runs, stopped and joined when dropped (or
//! stopped for what it returned).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use crate::cpu::ThreadCpuClock;

/// A server thread that runs until its stop flag is set.
pub(super) struct ServerThread<T> {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<T>>,
    cpu: Option<ThreadCpuClock>,
}

impl<T: Send + 'static> ServerThread<T> {
    /// Run `serve` on a new thread; it must return soon after the flag it
    /// is given is set.
    pub(super) fn spawn(
        serve: impl FnOnce(&Arc<AtomicBool>) -> T + Send + 'static,
    ) -> ServerThread<T> {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let thread = std::thread::spawn(move || serve(&flag));
        let cpu = ThreadCpuClock::of(&thread);
        ServerThread {
            stop,
            thread: Some(thread),
            cpu,
        }
    }

    /// CPU time its thread has used so far, while it runs.
    pub(super) fn cpu_time(&self) -> Option<Duration> {
        self.cpu
            .and_then(|c| c.now_while_running(self.thread.as_ref()))
    }

    /// Stop it and take what it returned (`None`: it panicked).
    pub(super) fn stop(mut self) -> Option<T> {
        self.stop.store(true, Ordering::Relaxed);
        self.thread.take().and_then(|t| t.join().ok())
    }
}

impl<T> Drop for ServerThread<T> {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
