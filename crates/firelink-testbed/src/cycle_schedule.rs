//! When the robot service's loop runs its next servo cycle: on a schedule
//! at the control rate, or at once for a command that is waiting.
//!
//! A command (a `servo_jp` point, say) that arrives between two cycles
//! would otherwise wait for the next scheduled cycle: anything from 0 to a
//! whole period, depending only on the phase at which its sender happens
//! to send. Instead, a cycle starts as soon as a command is waiting, once
//! at least [`CycleSchedule::min_gap`] has passed since the last cycle
//! started, and the schedule is re-phased from that cycle: the next one is
//! due a full period after it. So a command waits at most the minimum gap
//! (and the cycle's own I/O up to its write block), never for the period.
//!
//! What this keeps:
//! - the control rate never drops below the asked rate: every cycle is
//!   due at most a period after the one before (an early cycle only
//!   shortens one interval); a cycle late by up to the schedule's
//!   catch-up limit keeps the schedule's phase (the next is due a period
//!   after the deadline it missed: the cycles missed run back to back, so
//!   the average rate holds), one later than that is an overrun and the
//!   schedule restarts from it;
//! - the control law's period stays the real interval: the minimum gap
//!   (a fifth of the period) keeps the interval between an early cycle and
//!   the one before well inside the range the runner accepts as a period
//!   (a tenth to ten periods), so the interval it measures is the one that
//!   passed; a virtual clock moves by [`CycleSchedule::slot_interval`]
//!   (a period for each cycle caught up).
//!
//! Time is passed in (a [`Duration`] since an origin the caller chose):
//! the schedule reads no clock, and its tests run on made-up times.

use std::time::Duration;

/// How a cycle's start fell against the schedule.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CycleStart {
    /// Before its deadline, for a waiting command: the schedule re-phased
    /// from it.
    Early,
    /// At its deadline, or late by at most the catch-up limit: the
    /// schedule keeps its phase.
    OnSchedule,
    /// Later than the catch-up limit (the thread did not get a CPU for
    /// that long): the schedule restarts from it.
    Overrun,
}

impl CycleStart {
    /// Early 0, on schedule 1, overrun 2 (an index into counts of each).
    pub fn index(self) -> usize {
        match self {
            CycleStart::Early => 0,
            CycleStart::OnSchedule => 1,
            CycleStart::Overrun => 2,
        }
    }
}

/// What the loop should do now.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Due {
    /// Start a cycle now.
    Now,
    /// Wait until this time (or until a command arrives), then ask again.
    At(Duration),
}

/// The robot loop's cycle schedule ([module docs](self)).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CycleSchedule {
    period: Duration,
    min_gap: Duration,
    catch_up: Duration,
    /// The slots of the last two cycles: an early cycle's is its start,
    /// the others' their deadline.
    slots: [Option<Duration>; 2],
    /// When the next cycle is due (`None`: before the first, which runs at
    /// once).
    deadline: Option<Duration>,
    /// When the last cycle started.
    last_start: Option<Duration>,
}

impl CycleSchedule {
    /// A schedule of one cycle per `period`; an early cycle comes at least
    /// a fifth of a period after the last one; a cycle late by at most
    /// `catch_up` keeps the phase (the missed cycles then run back to
    /// back), a later one restarts the schedule.
    pub fn new(period: Duration, catch_up: Duration) -> CycleSchedule {
        CycleSchedule {
            period,
            min_gap: period / 5,
            catch_up,
            slots: [None; 2],
            deadline: None,
            last_start: None,
        }
    }

    /// The period.
    pub fn period(&self) -> Duration {
        self.period
    }

    /// The least time between the starts of two cycles when the second
    /// one runs early for a command.
    pub fn min_gap(&self) -> Duration {
        self.min_gap
    }

    /// Whether to start a cycle at `now`, with `command_waiting` saying
    /// whether a command is queued for the loop.
    pub fn due(&self, now: Duration, command_waiting: bool) -> Due {
        let (Some(deadline), Some(last)) = (self.deadline, self.last_start) else {
            return Due::Now;
        };
        let early_from = last + self.min_gap;
        let from = if command_waiting {
            deadline.min(early_from)
        } else {
            deadline
        };
        if now >= from { Due::Now } else { Due::At(from) }
    }

    /// A cycle starts at `now`: when the next one is due from here, and
    /// how this one fell against the schedule.
    pub fn start(&mut self, now: Duration) -> CycleStart {
        let (slot, kind) = match self.deadline {
            None => (now, CycleStart::OnSchedule),
            Some(d) if now < d => (now, CycleStart::Early),
            Some(d) if now <= d + self.catch_up => (d, CycleStart::OnSchedule),
            Some(_) => (now, CycleStart::Overrun),
        };
        self.deadline = Some(slot + self.period);
        self.slots = [self.slots[1], Some(slot)];
        self.last_start = Some(now);
        kind
    }

    /// When the next cycle is due (`None` before the first).
    pub fn deadline(&self) -> Option<Duration> {
        self.deadline
    }

    /// The interval between the slots of the last two cycles (an early
    /// cycle's slot is its start, the others' their deadline), a period at
    /// most: how far a virtual clock moves for the last cycle, so that the
    /// control law's period is the schedule's real interval and a thread
    /// that waited for a CPU does not stretch it. `None` before the
    /// second cycle.
    pub fn slot_interval(&self) -> Option<Duration> {
        match self.slots {
            [Some(a), Some(b)] => Some(b.saturating_sub(a).min(self.period)),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);
    const US: Duration = Duration::from_micros(1);

    /// Run a loop on made-up time: cycles take `io` each; commands arrive
    /// at the times of `arrivals`; the loop wakes exactly when asked.
    /// Returns every cycle's start and, per arrival, the start of the cycle
    /// that took it.
    fn simulate(
        period: Duration,
        io: Duration,
        arrivals: &[Duration],
        until: Duration,
    ) -> (Vec<Duration>, Vec<Duration>) {
        let mut schedule = CycleSchedule::new(period, period / 2);
        let mut now = Duration::ZERO;
        let mut starts = Vec::new();
        let mut taken_by = Vec::new();
        let mut next_arrival = 0;
        while now < until {
            let waiting = arrivals.get(next_arrival).is_some_and(|&a| a <= now);
            match schedule.due(now, waiting) {
                Due::Now => {
                    schedule.start(now);
                    starts.push(now);
                    while arrivals.get(next_arrival).is_some_and(|&a| a <= now) {
                        taken_by.push(now);
                        next_arrival += 1;
                    }
                    now += io;
                }
                // Woken at the time asked, or by the next arrival.
                Due::At(t) => {
                    now = match arrivals.get(next_arrival) {
                        Some(&a) if a > now && a < t => a,
                        _ => t,
                    };
                }
            }
        }
        (starts, taken_by)
    }

    #[test]
    fn without_commands_cycles_keep_the_period() {
        let (starts, _) = simulate(MS, 90 * US, &[], 10 * MS);
        let expected: Vec<Duration> = (0..10).map(|k| k * MS).collect();
        assert_eq!(starts, expected);
    }

    /// A command arriving at any phase of the period is taken by a cycle
    /// that starts at once (or at the minimum gap after the last start),
    /// never at the next deadline; the schedule re-phases from it.
    #[test]
    fn a_command_at_any_phase_starts_a_cycle_within_the_minimum_gap() {
        let period = MS;
        let gap = CycleSchedule::new(period, period / 2).min_gap();
        assert_eq!(gap, 200 * US);
        for phase_us in (0..1000).step_by(50) {
            let arrival = 5 * MS + phase_us * US;
            let (starts, taken) = simulate(period, 90 * US, &[arrival], 10 * MS);
            let last_before = *starts.iter().rev().find(|&&s| s < arrival).unwrap();
            let expected = arrival.max(last_before + gap);
            assert_eq!(taken, [expected], "arrival at phase {phase_us} us");
            // The wait is bounded by the gap, not by the period.
            assert!(taken[0] - arrival <= gap);
            // The cycle after it comes a full period later: re-phased.
            let after = starts.iter().find(|&&s| s > taken[0]).unwrap();
            assert_eq!(*after - taken[0], period);
        }
    }

    /// However the commands come (a 200 Hz stream at an odd phase, a burst,
    /// a reply to each cycle), no interval between cycle starts is longer
    /// than the period or shorter than the minimum gap: the rate never
    /// drops below the asked one and the control law's period stays in
    /// the range it accepts.
    #[test]
    fn intervals_stay_between_the_minimum_gap_and_the_period() {
        let period = MS;
        let stream: Vec<Duration> = (0..40).map(|k| k * 5 * MS + 333 * US).collect();
        let burst: Vec<Duration> = (0..200).map(|k| 3 * MS + k * 7 * US).collect();
        // A reply 150 us after every scheduled millisecond.
        let replies: Vec<Duration> = (0..200).map(|k| k * MS + 150 * US).collect();
        for arrivals in [stream, burst, replies] {
            let (starts, taken) = simulate(period, 90 * US, &arrivals, 200 * MS);
            assert_eq!(taken.len(), arrivals.len());
            for w in starts.windows(2) {
                let gap = w[1] - w[0];
                assert!(gap <= period, "{gap:?}");
                assert!(gap >= period / 5, "{gap:?}");
            }
            assert!(starts.len() >= 200, "{}", starts.len());
        }
    }

    #[test]
    fn a_late_cycle_keeps_the_phase_and_an_overrun_restarts_it() {
        let mut s = CycleSchedule::new(MS, MS / 2);
        assert_eq!(s.due(Duration::ZERO, false), Due::Now);
        assert_eq!(s.start(Duration::ZERO), CycleStart::OnSchedule);
        assert_eq!(s.due(500 * US, false), Due::At(MS));
        assert_eq!(s.due(500 * US, true), Due::Now);
        assert_eq!(s.due(100 * US, true), Due::At(200 * US));
        // 0.4 ms late: on schedule, the next still at 2 ms; its slot is
        // its deadline.
        assert_eq!(s.start(1400 * US), CycleStart::OnSchedule);
        assert_eq!(s.deadline(), Some(2 * MS));
        assert_eq!(s.slot_interval(), Some(MS));
        // 0.7 ms late: an overrun, the next a period after it.
        assert_eq!(s.start(2700 * US), CycleStart::Overrun);
        assert_eq!(s.deadline(), Some(3700 * US));
        assert_eq!(s.slot_interval(), Some(MS), "at most a period");
        // Early: re-phased; its slot is its start.
        assert_eq!(s.start(3000 * US), CycleStart::Early);
        assert_eq!(s.deadline(), Some(4 * MS));
        assert_eq!(s.slot_interval(), Some(300 * US));
    }

    /// A thread that could not run for 5 periods, with a catch-up limit of
    /// 10: the missed cycles run back to back, each in its own slot a
    /// period apart, and the count of cycles holds the rate.
    #[test]
    fn missed_cycles_within_the_catch_up_limit_run_back_to_back() {
        let mut s = CycleSchedule::new(MS, 10 * MS);
        s.start(Duration::ZERO);
        let mut now = 5 * MS + 300 * US;
        let mut cycles = 1;
        while let Due::Now = s.due(now, false) {
            assert_eq!(s.start(now), CycleStart::OnSchedule);
            assert_eq!(s.slot_interval(), Some(MS));
            cycles += 1;
            now += 90 * US;
        }
        assert_eq!(cycles, 6, "the cycles of 0..=5 ms");
        assert_eq!(s.deadline(), Some(6 * MS));
    }
}
