//! Precise waits on the real clock: sleep until shortly before the
//! deadline, then spin. `thread::sleep` alone overshoots by tens of
//! microseconds (timer slack, scheduling), too coarse for the broadcast
//! protocol's wait or a multi-kHz servo period.

use std::time::{Duration, Instant};

/// How long before the deadline sleeping stops and spinning starts.
const SPIN: Duration = Duration::from_micros(100);

/// Wait until `deadline`.
pub fn sleep_until(deadline: Instant) {
    let now = Instant::now();
    if deadline > now + SPIN {
        std::thread::sleep(deadline - now - SPIN);
    }
    while Instant::now() < deadline {
        std::hint::spin_loop();
    }
}

/// Wait for `duration` from now.
pub fn precise_sleep(duration: Duration) {
    sleep_until(Instant::now() + duration);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn never_returns_early() {
        let start = Instant::now();
        precise_sleep(Duration::from_micros(300));
        assert!(start.elapsed() >= Duration::from_micros(300));
        let past = Instant::now();
        sleep_until(past); // a deadline already passed returns at once
    }
}
