//! A host whose time is virtual, over a real port, and an in-process
//! emulator that keeps that time ([`Emulator::start_following`]): for
//! tests of a run over loopback UDP whose outcome must not depend on how
//! the machine schedules the host's or the server's thread.
//!
//! [`HostClockedPort`] wraps the host's port: its clock ([`Port::now`])
//! moves only when the host waits ([`Port::wait`], at once, without
//! sleeping), so a virtually paced robot sees every cycle exactly one
//! period long; the link filters a fault script adds through it see each
//! packet at the host's time too, so its `t=` moments are the host's. Each wait is recorded with the wall-clock instant it
//! happened at; the emulator handles each datagram at the host time in
//! effect when the datagram arrived (the kernel's receive stamp), so the
//! boards see the host's requests at the host's times, however late on
//! the wall clock either thread ran.
//!
//! The look-up is as good as the receive stamp, and it is not exact: a
//! datagram the kernel stamps only after the host's next wait (its
//! receive deferred under load), or an emulator thread pre-empted between
//! the two clock reads that convert the stamp, is handled one wait late
//! (or early), and a command then reaches the boards a period late. The
//! tests that use it assert outcomes such a shift does not change (which
//! board is named, amplifiers off, the bridge's counters), not
//! trajectories bit for bit.
//!
//! [`Emulator::start_following`]: super::Emulator::start_following

use std::collections::VecDeque;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use firelink_host::link_stats::LinkStats;
use firelink_host::port::{Direction, Verdict};
use firelink_host::{Dest, LinkFilter, Port, Result};

/// Waits remembered for the emulator's look-ups: far more than one servo
/// cycle makes (the emulator is never further behind the host than the
/// host's last read, inside the current cycle).
const STEPS_KEPT: usize = 256;

#[derive(Debug, Default)]
struct Steps {
    /// The host's time now.
    now: Duration,
    /// (wall-clock instant of a wait, host time after it), oldest first.
    steps: VecDeque<(Instant, Duration)>,
    /// The host time before the oldest step kept.
    before_oldest: Duration,
}

/// A host's virtual time, shared by its [`HostClockedPort`] and the
/// emulator that follows it. Starts at 0.
#[derive(Debug, Clone, Default)]
pub struct HostClock {
    steps: Arc<Mutex<Steps>>,
}

impl HostClock {
    /// A clock at 0.
    pub fn new() -> HostClock {
        HostClock::default()
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Steps> {
        self.steps.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// The host's time now.
    pub fn now(&self) -> Duration {
        self.lock().now
    }

    /// Let `d` of host time pass, at this wall-clock instant.
    pub fn advance(&self, d: Duration) {
        self.advance_at(d, Instant::now());
    }

    fn advance_at(&self, d: Duration, when: Instant) {
        let mut s = self.lock();
        s.now += d;
        let now = s.now;
        if s.steps.len() == STEPS_KEPT {
            if let Some((_, v)) = s.steps.pop_front() {
                s.before_oldest = v;
            }
        }
        s.steps.push_back((when, now));
    }

    /// The host's time at the wall-clock instant `at`: what it was after
    /// the last wait that happened at or before `at`.
    pub fn at(&self, at: Instant) -> Duration {
        let s = self.lock();
        s.steps
            .iter()
            .rev()
            .find(|(when, _)| *when <= at)
            .map_or(s.before_oldest, |(_, v)| *v)
    }
}

/// A port whose clock is a [`HostClock`]: every call goes to the wrapped
/// port except [`now`](Port::now) (the clock) and [`wait`](Port::wait)
/// (the clock advances, nothing sleeps). Overheard traffic is not waited
/// for either: `wait_until_heard` waits its whole limit on the clock.
pub struct HostClockedPort<P: Port> {
    inner: P,
    clock: HostClock,
}

impl<P: Port> HostClockedPort<P> {
    /// `inner` on `clock`.
    pub fn new(inner: P, clock: HostClock) -> HostClockedPort<P> {
        HostClockedPort { inner, clock }
    }

    /// The wrapped port.
    pub fn inner(&self) -> &P {
        &self.inner
    }

    /// The wrapped port, to change (what goes through it bypasses the
    /// clock).
    pub fn inner_mut(&mut self) -> &mut P {
        &mut self.inner
    }
}

impl<P: Port> Port for HostClockedPort<P> {
    fn name(&self) -> &str {
        self.inner.name()
    }
    fn read_quadlet(&mut self, dest: Dest, offset: u64) -> Result<u32> {
        self.inner.read_quadlet(dest, offset)
    }
    fn write_quadlet(&mut self, dest: Dest, offset: u64, value: u32) -> Result<()> {
        self.inner.write_quadlet(dest, offset, value)
    }
    fn read_block(&mut self, dest: Dest, offset: u64, out: &mut [u8]) -> Result<()> {
        self.inner.read_block(dest, offset, out)
    }
    fn write_block(&mut self, dest: Dest, offset: u64, data: &[u8]) -> Result<()> {
        self.inner.write_block(dest, offset, data)
    }
    fn start_write_quadlet(&mut self, dest: Dest, offset: u64, value: u32) -> Result<()> {
        self.inner.start_write_quadlet(dest, offset, value)
    }
    fn start_write_block(&mut self, dest: Dest, offset: u64, data: &[u8]) -> Result<()> {
        self.inner.start_write_block(dest, offset, data)
    }
    fn wait(&mut self, duration: Duration) {
        self.clock.advance(duration);
    }
    fn begin_cycle(&mut self) {
        self.inner.begin_cycle();
    }
    fn end_cycle(&mut self) {
        self.inner.end_cycle();
    }
    fn receive_broadcast_response(&mut self, out: &mut [u8]) -> Option<Result<()>> {
        self.inner.receive_broadcast_response(out)
    }
    fn broadcast_wait(&self, boards: usize) -> Duration {
        self.inner.broadcast_wait(boards)
    }
    fn hub_clock_hz(&self) -> u32 {
        self.inner.hub_clock_hz()
    }
    fn now(&self) -> Duration {
        self.clock.now()
    }
    fn generation(&self) -> u32 {
        self.inner.generation()
    }
    fn acknowledges_writes(&self) -> bool {
        self.inner.acknowledges_writes()
    }
    fn refuses_broadcast_registers(&self) -> bool {
        self.inner.refuses_broadcast_registers()
    }
    fn link_stats(&self) -> LinkStats {
        self.inner.link_stats()
    }
    fn candidate_nodes(&self) -> core::ops::Range<u8> {
        self.inner.candidate_nodes()
    }
    fn add_link_filter(&mut self, filter: Box<dyn LinkFilter>) -> Result<()> {
        // The filter was started on this port's clock (a fault script's
        // `t=` counts from the host's time): it is given the host's time,
        // not the wrapped port's wall clock.
        self.inner.add_link_filter(Box::new(OnHostClock {
            filter,
            clock: self.clock.clone(),
        }))
    }
    fn takes_link_filters(&self) -> bool {
        self.inner.takes_link_filters()
    }
}

/// A link filter that sees each packet at the host's time (the wrapped
/// port calls it with its own clock's time, which is thrown away).
struct OnHostClock {
    filter: Box<dyn LinkFilter>,
    clock: HostClock,
}

impl LinkFilter for OnHostClock {
    fn packet(&mut self, _port_ps: u64, direction: Direction, packet: &mut [u8]) -> Verdict {
        let at_ps = u64::try_from(self.clock.now().as_nanos())
            .unwrap_or(u64::MAX)
            .saturating_mul(1000);
        self.filter.packet(at_ps, direction, packet)
    }

    fn is_spent(&self) -> bool {
        self.filter.is_spent()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_clock_answers_for_the_instant_asked() {
        let clock = HostClock::new();
        let start = Instant::now();
        let at = |us: u64| start + Duration::from_micros(us);
        assert_eq!(clock.at(start), Duration::ZERO);
        clock.advance_at(Duration::from_millis(1), at(10));
        clock.advance_at(Duration::from_millis(2), at(20));
        assert_eq!(clock.now(), Duration::from_millis(3));
        // Before the first wait: 0; from it to the second: 1 ms; then 3 ms.
        assert_eq!(clock.at(at(9)), Duration::ZERO);
        assert_eq!(clock.at(at(10)), Duration::from_millis(1));
        assert_eq!(clock.at(at(19)), Duration::from_millis(1));
        assert_eq!(clock.at(at(25)), Duration::from_millis(3));
        // Old steps forgotten: an instant before every kept step gets the
        // time before the oldest kept (the first two are gone).
        for k in 0..STEPS_KEPT as u64 {
            clock.advance_at(Duration::from_micros(1), at(30 + k));
        }
        assert_eq!(clock.at(at(15)), Duration::from_millis(3));
        assert_eq!(clock.at(at(30)), Duration::from_micros(3001));
    }

    /// Records the times it is given.
    struct Times(Arc<Mutex<Vec<u64>>>);

    impl LinkFilter for Times {
        fn packet(&mut self, at_ps: u64, _: Direction, _: &mut [u8]) -> Verdict {
            self.0.lock().unwrap().push(at_ps);
            Verdict::Pass
        }
    }

    #[test]
    fn a_link_filter_sees_the_hosts_time_not_the_wrapped_ports() {
        let clock = HostClock::new();
        let seen = Arc::new(Mutex::new(Vec::new()));
        let mut on_host = OnHostClock {
            filter: Box::new(Times(Arc::clone(&seen))),
            clock: clock.clone(),
        };
        let mut packet = [0u8; 16];
        assert_eq!(
            on_host.packet(123_456_789, Direction::Sent, &mut packet),
            Verdict::Pass
        );
        clock.advance_at(Duration::from_micros(250), Instant::now());
        on_host.packet(5, Direction::Received, &mut packet);
        assert_eq!(*seen.lock().unwrap(), [0, 250_000_000]);
    }
}
