//! Long calls that Ctrl-C interrupts.
//!
//! A call that releases the GIL for long (the demo, the benchmark, a
//! thousand cycles in Rust, a long wait, a scan with long time-outs) runs
//! its work on a worker thread; the calling thread meanwhile runs Python's
//! signal handlers every [`POLL`] (`Python::check_signals`, which does
//! something only on the main thread, where Python's handlers run). When a
//! handler raises (Ctrl-C: `KeyboardInterrupt`), the call ends with that
//! exception:
//!
//! - [`until_interrupted`]: the work borrows what it works on and obeys a
//!   [`StopRequest`]; the request is set and the worker waited for. A robot
//!   loop returns at its next cycle and its I/O system, dropped, powers
//!   down the boards it energised.
//! - [`abandon_on_interrupt`]: the work owns everything it uses and cannot
//!   be stopped (the benchmark, a scan); the call returns at once and the
//!   worker finishes on its own, its result dropped.

use std::sync::mpsc::{self, RecvTimeoutError};
use std::time::Duration;

use pyo3::prelude::*;

use firelink_host::stop::StopRequest;

/// How often a waiting call runs Python's signal handlers.
pub(crate) const POLL: Duration = Duration::from_millis(100);

/// Python's signal handlers, run now; their exception, if one raised.
fn signalled() -> Option<PyErr> {
    Python::attach(|py| py.check_signals().err())
}

/// Run `work` on a worker thread with the GIL released, Python's signal
/// handlers running meanwhile. When one raises, `work`'s stop request is
/// set, the worker is waited for, and the handler's exception is returned
/// instead of the work's result.
///
/// # Errors
/// The signal handler's exception (`KeyboardInterrupt`).
pub(crate) fn until_interrupted<T: Send>(
    py: Python<'_>,
    work: impl FnOnce(&StopRequest) -> T + Send,
) -> PyResult<T> {
    let stop = StopRequest::new();
    let (result, raised) = py.detach(|| {
        std::thread::scope(|s| {
            let (done, finished) = mpsc::channel::<()>();
            let stop = &stop;
            let worker = s.spawn(move || {
                let r = work(stop);
                drop(done);
                r
            });
            let mut raised = None;
            while let Err(RecvTimeoutError::Timeout) = finished.recv_timeout(POLL) {
                if raised.is_none() {
                    raised = signalled();
                    if raised.is_some() {
                        stop.request();
                    }
                }
            }
            let result = worker
                .join()
                .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
            (result, raised)
        })
    });
    match raised {
        Some(e) => Err(e),
        None => Ok(result),
    }
}

/// Run `work` on a thread of its own with the GIL released, Python's
/// signal handlers running meanwhile. When one raises, its exception is
/// returned at once; the thread finishes the work on its own and drops
/// the result.
///
/// # Errors
/// The signal handler's exception (`KeyboardInterrupt`).
pub(crate) fn abandon_on_interrupt<T: Send + 'static>(
    py: Python<'_>,
    work: impl FnOnce() -> T + Send + 'static,
) -> PyResult<T> {
    let (send, receive) = mpsc::channel::<T>();
    let worker = std::thread::spawn(move || {
        // The receiver is gone after an interrupt: nobody wants it then.
        let _ = send.send(work());
    });
    let outcome = py.detach(move || {
        loop {
            match receive.recv_timeout(POLL) {
                Ok(result) => return Ok(result),
                Err(RecvTimeoutError::Timeout) => {
                    if let Some(e) = signalled() {
                        return Err(Some(e));
                    }
                }
                Err(RecvTimeoutError::Disconnected) => return Err(None),
            }
        }
    });
    match outcome {
        Ok(result) => {
            let _ = worker.join();
            Ok(result)
        }
        Err(Some(e)) => Err(e),
        // The worker ended without a result: it panicked.
        Err(None) => match worker.join() {
            Err(panic) => std::panic::resume_unwind(panic),
            Ok(()) => Err(crate::errors::error(
                py,
                "FirelinkError",
                "the worker thread ended without a result".to_string(),
            )),
        },
    }
}
