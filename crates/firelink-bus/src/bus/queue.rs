//! The event queue: every event in one total order, (virtual time,
//! insertion order), kept in three places by how it behaves.
//!
//! - General events (arbitration, packet starts, acks, notifications...)
//!   sit in a sorted ring buffer (a few at a time, nearly always queued
//!   later than those already there: an insertion at or near the back
//!   and a pop from the front cost less than a heap's sifting).
//! - Node timers sit in a sorted list, so a timer that is cancelled or
//!   set again leaves at once instead of lingering in the queue until its
//!   time (a PC's 100 ms split time-outs, cancelled after every read,
//!   would otherwise pile up by the hundred).
//! - A packet's deliveries, one per node it reaches, form a *wave*: their
//!   arrival times are known together and they come out one by one in
//!   order, without a queue operation each.
//!
//! Each event takes its insertion number when it is queued (a wave takes
//! one per delivery, in the order the nodes are listed), and `pop` always
//! returns the smallest (time, number) of the three: the order is exactly
//! the one a single priority queue would give.

use std::cell::Cell;
use std::collections::VecDeque;

use super::Ev;
use crate::time::SimTime;
use crate::trace::PacketId;

/// A general event.
#[derive(Debug)]
struct Queued {
    time: SimTime,
    seq: u64,
    epoch: Option<u64>,
    ev: Ev,
}

/// One delivery of a wave.
#[derive(Debug, Clone, Copy)]
struct Arrival {
    time: SimTime,
    seq: u64,
    node: usize,
}

/// The deliveries of one packet, in (time, number) order.
#[derive(Debug)]
struct Wave {
    sub: PacketId,
    epoch: u64,
    arrivals: Vec<Arrival>,
    next: usize,
}

impl Wave {
    fn head(&self) -> Option<(SimTime, u64)> {
        self.arrivals.get(self.next).map(|a| (a.time, a.seq))
    }
}

/// An event taken off the queue.
#[derive(Debug)]
pub(super) struct Popped {
    pub time: SimTime,
    /// The bus epoch the event belongs to (`None`: any).
    pub epoch: Option<u64>,
    pub ev: Ev,
}

/// A packet's delivery taken off the queue.
#[derive(Debug, Clone, Copy)]
pub(super) struct Delivery {
    pub time: SimTime,
    /// The bus epoch of the packet.
    pub epoch: u64,
    pub sub: PacketId,
    pub node: usize,
}

/// An event taken off the queue by [`EventQueue::pop_until`].
#[derive(Debug)]
pub(super) enum Taken {
    Delivery(Delivery),
    Event(Popped),
}

/// Where the next event comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Source {
    General,
    Timer,
    Wave(usize),
}

/// The queue. See the module docs.
#[derive(Debug, Default)]
pub(super) struct EventQueue {
    /// General events in (time, number) order, the next first.
    general: VecDeque<Queued>,
    /// ((time, number), (node, token)), latest first: the next timer is
    /// the last (a handful are armed at a time; a sorted vector beats a
    /// tree there).
    timers: Vec<((SimTime, u64), (usize, u64))>,
    waves: Vec<Wave>,
    /// Arrival buffers of finished waves, kept for the next ones.
    spare: Vec<Vec<Arrival>>,
    seq: u64,
    /// The next event as last looked up (`None`: to be looked up again),
    /// kept while events are queued and taken (`pop_until` looks once and
    /// takes the event; `peek_time` only looks), and while it is known, a
    /// (time, number) no later than the first event of every other source
    /// (so that a source that goes on, or a new event, can often settle the
    /// next event without looking at the others again).
    next: Cell<Option<(Source, SimTime, u64)>>,
    runner_up: Cell<Option<(SimTime, u64)>>,
}

impl EventQueue {
    fn next_seq(&mut self) -> u64 {
        self.seq += 1;
        self.seq
    }

    /// An event `key` = (time, number) was queued in `source`, where it is
    /// now the first if it comes before the next event known: the next
    /// event stays known. (The number is the highest yet, so `key` is
    /// never equal to another.)
    fn queued(&self, source: Source, key: (SimTime, u64)) {
        let Some((_, time, seq)) = self.next.get() else {
            return;
        };
        if key < (time, seq) {
            // The old next event is now no later than the first of every
            // source but the new one's.
            self.next.set(Some((source, key.0, key.1)));
            self.runner_up.set(Some((time, seq)));
        } else if self.runner_up.get().is_none_or(|r| key < r) {
            self.runner_up.set(Some(key));
        }
    }

    /// After the next event was taken from `source`: its new first event
    /// is the next one if it comes before every other source's first
    /// (the others did not change). Otherwise the next event is looked
    /// up again when asked for.
    fn goes_on(&self, source: Source, head: Option<(SimTime, u64)>) {
        if let Some(head) = head
            && self.runner_up.get().is_none_or(|r| head < r)
        {
            self.next.set(Some((source, head.0, head.1)));
        }
    }

    /// Queue `ev` at `time`.
    pub fn push(&mut self, time: SimTime, epoch: Option<u64>, ev: Ev) {
        let seq = self.next_seq();
        let q = Queued {
            time,
            seq,
            epoch,
            ev,
        };
        // Its number is the highest yet: it goes after every event at
        // its time or earlier.
        if self.general.back().is_none_or(|last| last.time <= time) {
            self.general.push_back(q);
        } else {
            let at = self.general.partition_point(|e| e.time <= time);
            self.general.insert(at, q);
        }
        self.queued(Source::General, (time, seq));
    }

    /// Queue node `node`'s timer `token` at `time`; returns its number
    /// (what [`cancel_timer`](Self::cancel_timer) needs, and the stamp its
    /// event carries).
    pub fn push_timer(&mut self, time: SimTime, node: usize, token: u64) -> u64 {
        let seq = self.next_seq();
        let key = (time, seq);
        let at = self.timers.partition_point(|t| t.0 > key);
        self.timers.insert(at, (key, (node, token)));
        self.queued(Source::Timer, key);
        seq
    }

    /// Take a timer queued with [`push_timer`](Self::push_timer) out again.
    pub fn cancel_timer(&mut self, time: SimTime, seq: u64) {
        let key = (time, seq);
        if let Ok(i) = self.timers.binary_search_by(|t| key.cmp(&t.0)) {
            self.timers.remove(i);
            // Only the next event leaving changes which is next (a
            // runner-up that left stays a bound no later than the rest).
            if self
                .next
                .get()
                .is_some_and(|n| n.0 == Source::Timer && (n.1, n.2) == key)
            {
                self.next.set(None);
            }
        }
    }

    /// Queue the deliveries of packet `sub` (epoch `epoch`) to `arrivals`:
    /// (time, node) in the order they are numbered.
    pub fn push_wave(
        &mut self,
        sub: PacketId,
        epoch: u64,
        arrivals: impl IntoIterator<Item = (SimTime, usize)>,
    ) {
        let mut list = self.spare.pop().unwrap_or_default();
        list.clear();
        for (time, node) in arrivals {
            let seq = self.next_seq();
            list.push(Arrival { time, seq, node });
        }
        if list.is_empty() {
            self.spare.push(list);
            return;
        }
        // Numbered in listing order: already in (time, number) order when
        // listed in time order, as the nearest-first listing is (the sort
        // only for a listing by ID with hop delays).
        if !list.is_sorted_by_key(|a| a.time) {
            list.sort_unstable_by_key(|a| (a.time, a.seq));
        }
        let wave = Wave {
            sub,
            epoch,
            arrivals: list,
            next: 0,
        };
        let head = wave.head();
        self.waves.push(wave);
        if let Some(head) = head {
            self.queued(Source::Wave(self.waves.len() - 1), head);
        }
    }

    /// The source of the next event and its (time, number).
    #[inline]
    fn first(&self) -> Option<(Source, SimTime, u64)> {
        if let Some(next) = self.next.get() {
            return Some(next);
        }
        let found = self.find_first();
        self.next.set(found);
        found
    }

    #[inline(never)]
    fn find_first(&self) -> Option<(Source, SimTime, u64)> {
        let mut best: Option<(Source, SimTime, u64)> = None;
        let mut second: Option<(SimTime, u64)> = None;
        let mut consider = |source: Source, key: (SimTime, u64)| match best {
            Some(b) if key >= (b.1, b.2) => {
                if second.is_none_or(|s| key < s) {
                    second = Some(key);
                }
            }
            _ => {
                if let Some(b) = best {
                    second = Some((b.1, b.2));
                }
                best = Some((source, key.0, key.1));
            }
        };
        if let Some(q) = self.general.front() {
            consider(Source::General, (q.time, q.seq));
        }
        if let Some(&(key, _)) = self.timers.last() {
            consider(Source::Timer, key);
        }
        for (i, w) in self.waves.iter().enumerate() {
            if let Some(key) = w.head() {
                consider(Source::Wave(i), key);
            }
        }
        self.runner_up.set(second);
        best
    }

    /// Time of the next event.
    pub fn peek_time(&self) -> Option<SimTime> {
        self.first().map(|f| f.1)
    }

    /// Take the next event.
    #[cfg(test)]
    pub fn pop(&mut self) -> Option<Popped> {
        match self.pop_until(SimTime::MAX)? {
            Taken::Event(p) => Some(p),
            Taken::Delivery(d) => Some(Popped {
                time: d.time,
                epoch: Some(d.epoch),
                ev: Ev::Deliver {
                    sub: d.sub,
                    node: d.node,
                },
            }),
        }
    }

    /// Take the next event if it comes at `deadline` or before (one look
    /// at the next event, where a peek at its time and a pop took two or
    /// three); a packet's delivery, the commonest event, is handed over
    /// without making an [`Ev`] of it.
    #[inline]
    pub fn pop_until(&mut self, deadline: SimTime) -> Option<Taken> {
        let (source, time, _) = self.first()?;
        if time > deadline {
            return None;
        }
        self.next.set(None);
        match source {
            Source::Wave(i) => self.take_delivery(i).map(Taken::Delivery),
            Source::General => {
                let q = self.general.pop_front()?;
                self.goes_on(source, self.general.front().map(|f| (f.time, f.seq)));
                Some(Taken::Event(Popped {
                    time: q.time,
                    epoch: q.epoch,
                    ev: q.ev,
                }))
            }
            Source::Timer => {
                let ((time, seq), (node, token)) = self.timers.pop()?;
                self.goes_on(source, self.timers.last().map(|t| t.0));
                Some(Taken::Event(Popped {
                    time,
                    epoch: None,
                    ev: Ev::Timer {
                        node,
                        token,
                        stamp: seq,
                    },
                }))
            }
        }
    }

    /// Take the next delivery of wave `i` (inlined into
    /// [`pop_until`](Self::pop_until): the delivery is handed over in
    /// registers, not through memory).
    #[inline(always)]
    fn take_delivery(&mut self, i: usize) -> Option<Delivery> {
        let wave = self.waves.get_mut(i)?;
        let a = *wave.arrivals.get(wave.next)?;
        wave.next += 1;
        let (sub, epoch) = (wave.sub, wave.epoch);
        if wave.next >= wave.arrivals.len() {
            let done = self.waves.swap_remove(i);
            self.spare.push(done.arrivals);
        } else {
            let head = wave.head();
            self.goes_on(Source::Wave(i), head);
        }
        Some(Delivery {
            time: a.time,
            epoch,
            sub,
            node: a.node,
        })
    }

    /// Take the next delivery of packet `sub` of bus epoch `epoch` if it
    /// is the next event and comes at `deadline` or before (what a batch
    /// of deliveries goes on with; `None`, nothing taken: another event
    /// comes first, the packet has no delivery left, or a bus reset
    /// since made its deliveries stale).
    #[inline]
    pub fn pop_wave_next(
        &mut self,
        sub: PacketId,
        epoch: u64,
        deadline: SimTime,
    ) -> Option<Delivery> {
        let (source, time, _) = self.first()?;
        let Source::Wave(i) = source else {
            return None;
        };
        let wave = self.waves.get(i)?;
        if time > deadline || wave.sub != sub || wave.epoch != epoch {
            return None;
        }
        self.next.set(None);
        self.take_delivery(i)
    }

    /// Whether nothing is queued but cycle-start ticks.
    pub fn only_cycle_ticks(&self) -> bool {
        self.timers.is_empty()
            && self.waves.is_empty()
            && self.general.iter().all(|q| matches!(q.ev, Ev::CycleTick))
    }

    /// Events queued.
    #[cfg(test)]
    pub fn len(&self) -> usize {
        self.general.len()
            + self.timers.len()
            + self
                .waves
                .iter()
                .map(|w| w.arrivals.len() - w.next)
                .sum::<usize>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn t(ns: u64) -> SimTime {
        SimTime(ns * 1000)
    }

    /// Drain the queue into (time, kind) pairs.
    fn drain(q: &mut EventQueue) -> Vec<(SimTime, String)> {
        let mut out = Vec::new();
        while let Some(p) = q.pop() {
            let what = match p.ev {
                Ev::Timer { token, .. } => format!("timer {token}"),
                Ev::Deliver { node, .. } => format!("deliver {node}"),
                Ev::Arbitrate => "arbitrate".to_string(),
                other => format!("{other:?}"),
            };
            out.push((p.time, what));
        }
        out
    }

    #[test]
    fn the_three_sources_come_out_in_time_then_insertion_order() {
        let mut q = EventQueue::default();
        q.push(t(10), None, Ev::Arbitrate);
        // Nodes 0..3 reached at 12, 10, 12 (numbered in that order).
        q.push_wave(7, 0, [(t(12), 0), (t(10), 1), (t(12), 2)]);
        q.push_timer(t(10), 5, 1);
        q.push_timer(t(11), 5, 2);
        let got = drain(&mut q);
        let want = [
            (t(10), "arbitrate"),
            (t(10), "deliver 1"),
            (t(10), "timer 1"),
            (t(11), "timer 2"),
            (t(12), "deliver 0"),
            (t(12), "deliver 2"),
        ];
        assert_eq!(got.len(), want.len());
        for (g, w) in got.iter().zip(want) {
            assert_eq!((g.0, g.1.as_str()), w);
        }
        assert_eq!(q.len(), 0);
        assert!(q.only_cycle_ticks());
    }

    #[test]
    fn general_events_queued_out_of_time_order_come_out_in_time_then_insertion_order() {
        let mut q = EventQueue::default();
        let tokens = [(30, 1), (10, 2), (20, 3), (10, 4), (5, 5), (20, 6), (40, 7)];
        for (ns, node) in tokens {
            q.push(t(ns), None, Ev::Unmute { node });
        }
        let mut got = Vec::new();
        while let Some(p) = q.pop() {
            let Ev::Unmute { node } = p.ev else {
                panic!("not an unmute: {:?}", p.ev);
            };
            got.push((p.time, node));
        }
        let want: Vec<(SimTime, usize)> =
            [(5, 5), (10, 2), (10, 4), (20, 3), (20, 6), (30, 1), (40, 7)]
                .iter()
                .map(|&(ns, node)| (t(ns), node))
                .collect();
        assert_eq!(got, want);
    }

    /// Every event pushed, timer cancelled and event taken, in a long
    /// pseudo-random mix, against a plain sorted list of (time, number):
    /// the queue's kept next event never lets one out of order.
    #[test]
    fn a_random_mix_comes_out_as_one_sorted_list_would() {
        let mut q = EventQueue::default();
        // (time, number) -> what the event is: 0 general, 1 timer, 2 delivery.
        let mut model: std::collections::BTreeMap<(SimTime, u64), u8> =
            std::collections::BTreeMap::new();
        let mut seq = 0u64;
        let mut timers: Vec<(SimTime, u64)> = Vec::new();
        let mut rng = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = move |n: u64| {
            rng = rng
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (rng >> 33) % n
        };
        let mut now = 0u64;
        let mut taken = 0;
        for _ in 0..20_000 {
            // Times from now on, often equal (ties are by number).
            match next(9) {
                0..=1 => {
                    let at = SimTime(now + next(6) * 10);
                    seq += 1;
                    // The number goes in as the node, to be checked.
                    q.push(at, None, Ev::Unmute { node: seq as usize });
                    model.insert((at, seq), 0);
                }
                2 => {
                    let at = SimTime(now + next(6) * 10);
                    seq += 1;
                    let stamp = q.push_timer(at, seq as usize, 0);
                    assert_eq!(stamp, seq);
                    model.insert((at, seq), 1);
                    timers.push((at, seq));
                }
                3 if !timers.is_empty() => {
                    let (at, s) = timers.swap_remove(next(timers.len() as u64) as usize);
                    q.cancel_timer(at, s);
                    model.remove(&(at, s));
                }
                4 => {
                    let arrivals: Vec<(SimTime, usize)> = (0..next(4))
                        .map(|_| {
                            seq += 1;
                            let at = SimTime(now + next(4) * 10);
                            model.insert((at, seq), 2);
                            (at, seq as usize)
                        })
                        .collect();
                    q.push_wave(7, 0, arrivals);
                }
                _ => {
                    let want = model.keys().next().copied();
                    assert_eq!(q.peek_time(), want.map(|k| k.0));
                    let Some(p) = q.pop() else {
                        assert!(want.is_none());
                        continue;
                    };
                    let (key, kind) = model.pop_first().unwrap();
                    let number = match p.ev {
                        Ev::Unmute { node } => (0, node),
                        Ev::Timer { node, stamp, .. } => {
                            assert_eq!(stamp, node as u64);
                            timers.retain(|t| *t != key);
                            (1, node)
                        }
                        Ev::Deliver { node, .. } => (2, node),
                        other => panic!("not queued here: {other:?}"),
                    };
                    assert_eq!((p.time, number), (key.0, (kind, key.1 as usize)));
                    now = key.0.0;
                    taken += 1;
                }
            }
        }
        assert!(taken > 5_000, "{taken} taken");
        while let Some(p) = q.pop() {
            let (key, _) = model.pop_first().unwrap();
            assert_eq!(p.time, key.0);
        }
        assert!(model.is_empty());
    }

    #[test]
    fn a_cancelled_timer_leaves_nothing_behind() {
        let mut q = EventQueue::default();
        let seq = q.push_timer(t(100), 0, 9);
        assert_eq!(q.len(), 1);
        q.cancel_timer(t(100), seq);
        assert_eq!(q.len(), 0);
        assert!(q.pop().is_none());
    }

    #[test]
    fn events_queued_while_a_wave_runs_interleave_by_time() {
        let mut q = EventQueue::default();
        q.push_wave(1, 3, [(t(5), 0), (t(9), 1)]);
        let first = q.pop().unwrap();
        assert_eq!(first.time, t(5));
        assert_eq!(first.epoch, Some(3));
        // Queued later but earlier than the wave's second delivery.
        q.push(t(7), None, Ev::Arbitrate);
        // Queued later at the same time: after it.
        q.push(t(9), None, Ev::Arbitrate);
        let rest = drain(&mut q);
        let kinds: Vec<&str> = rest.iter().map(|r| r.1.as_str()).collect();
        assert_eq!(kinds, ["arbitrate", "deliver 1", "arbitrate"]);
    }
}
