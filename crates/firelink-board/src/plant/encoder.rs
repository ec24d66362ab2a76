//! A quadrature encoder and the FPGA's edge-timing velocity measurement.
//!
//! The encoder turns a continuous shaft position (in counts, fractional)
//! into a count and A/B levels; every count change is one quadrature edge,
//! timestamped by interpolation inside the integration sub-step, so the
//! edge timing is exact to the picosecond for motion that is linear over a
//! sub-step.
//!
//! The velocity fields are what firmware Rev 7+ latches
//! (`fpga-board.md` section 3, and the public host library's reading of
//! them): all in 49.152 MHz clocks.
//! - *period*: the time of one full quadrature cycle (4 counts), between
//!   the latest edge and the previous edge of the same type. While no new
//!   edge arrives the free-running counter for the next expected edge is
//!   reported once it exceeds the latched value, so a stopping motor shows
//!   a growing period (a velocity decaying to zero) rather than the last
//!   speed forever. Fewer than four same-direction intervals (after
//!   power-up or a reversal) are extrapolated to a full cycle and flagged
//!   *partial*; a reversal within the cycle sets *direction changed*.
//! - *QTR1*: the latest quarter cycle (between the last two edges);
//!   *QTR5*: the quarter cycle that ended four edges earlier, i.e. the same
//!   edge type one cycle before, for acceleration estimates. Both carry
//!   their direction and which edge ended them.
//! - *RUN*: clocks since the latest edge.
//!
//! Each value has 26 bits; beyond that it saturates and sets its overflow
//! flag.

use crate::time::SimTime;

/// Largest period value, 26 bits.
pub const PERIOD_MAX: u32 = (1 << 26) - 1;

/// Edges remembered: enough for QTR5 (edges 0, 4 and 5).
const HISTORY: usize = 6;

/// Which edge a quadrature transition is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum EdgeKind {
    /// A rising.
    ARise = 0,
    /// A falling.
    AFall = 1,
    /// B rising.
    BRise = 2,
    /// B falling.
    BFall = 3,
}

impl EdgeKind {
    /// One-hot mask of this edge (bit 0 = A rising .. bit 3 = B falling).
    pub fn mask(self) -> u8 {
        1 << (self as u8)
    }

    /// The edge crossed when the count moves from `from` to `from + 1`
    /// (`up`) or `from - 1`. Forward order: A rises, B rises, A falls,
    /// B falls (A leads B); backwards each edge is the reverse of the
    /// forward one.
    #[inline]
    fn of_transition(from: i64, up: bool) -> EdgeKind {
        use EdgeKind::{AFall, ARise, BFall, BRise};
        // By quadrature state, down then up (a look-up, no branch).
        const KINDS: [EdgeKind; 8] = [BRise, AFall, BFall, ARise, ARise, BRise, AFall, BFall];
        let index = quadrature_state(from) as usize | (usize::from(up) << 2);
        KINDS.get(index).copied().unwrap_or(ARise)
    }
}

/// One remembered edge.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Edge {
    /// System clock counter at the edge.
    clock: u64,
    /// The count went up.
    up: bool,
    kind: EdgeKind,
}

/// The full-cycle period measurement (register ENC_PERIOD).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PeriodField {
    /// Clocks per full quadrature cycle (26 bits).
    pub clocks: u32,
    /// The value saturated (too slow, or no edges yet).
    pub overflow: bool,
    /// The latest edge counted up.
    pub up: bool,
    /// The direction changed within the cycle measured.
    pub direction_changed: bool,
    /// Two edges in the same clock: the FPGA could not follow.
    pub error: bool,
    /// Fewer than four same-direction intervals were available.
    pub partial: bool,
}

/// A quarter-cycle measurement (registers ENC_QTR1, ENC_QTR5).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct QuarterField {
    /// Clocks of the quarter cycle (26 bits).
    pub clocks: u32,
    /// The value saturated, or no such quarter yet.
    pub overflow: bool,
    /// The edge ending the quarter counted up.
    pub up: bool,
    /// One-hot edge ending the quarter ([`EdgeKind::mask`]); 0 if none.
    pub edge_mask: u8,
}

/// The running counter (register ENC_RUN).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RunField {
    /// Clocks since the latest edge (26 bits).
    pub clocks: u32,
    /// The value saturated.
    pub overflow: bool,
}

/// All velocity fields at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct VelocityFields {
    /// Full-cycle period.
    pub period: PeriodField,
    /// Latest quarter cycle.
    pub qtr1: QuarterField,
    /// The quarter cycle four edges earlier.
    pub qtr5: QuarterField,
    /// Clocks since the latest edge.
    pub run: RunField,
}

/// A full quadrature cycle from `clocks` over `quarters` (1..=4) quarter
/// cycles: `clocks * 4 / quarters`, by constants (no division by a
/// variable).
fn quarters_to_cycle(clocks: u64, quarters: usize) -> u64 {
    let x = clocks.saturating_mul(4);
    match quarters {
        1 => x,
        2 => x / 2,
        3 => x / 3,
        _ => x / 4,
    }
}

fn saturate(clocks: u64) -> (u32, bool) {
    if clocks > u64::from(PERIOD_MAX) {
        (PERIOD_MAX, true)
    } else {
        (clocks as u32, false)
    }
}

/// Encoder state: count, levels and the edge history.
#[derive(Debug, Clone)]
pub struct Encoder {
    counts_per_rev: u32,
    count: i64,
    /// The last edges, newest first: `recent[0]` is the most recent; the
    /// first `stored` of them are valid.
    recent: [Edge; HISTORY],
    stored: usize,
    /// How many of the stored edges, newest first, went the newest's
    /// way (the run `fields_at_clock` measures; 0 with none stored).
    same: usize,
    edge_count: u64,
}

impl PartialEq for Encoder {
    fn eq(&self, other: &Self) -> bool {
        self.counts_per_rev == other.counts_per_rev
            && self.count == other.count
            && self.edge_count == other.edge_count
            && self.same == other.same
            && self.stored == other.stored
            && self.edges() == other.edges()
    }
}

impl Encoder {
    /// An encoder whose shaft sits at `position` counts (fractional).
    pub fn new(counts_per_rev: u32, position: f64) -> Encoder {
        let unused = Edge {
            clock: 0,
            up: false,
            kind: EdgeKind::ARise,
        };
        Encoder {
            counts_per_rev: counts_per_rev.max(1),
            count: floor_count(position),
            recent: [unused; HISTORY],
            stored: 0,
            same: 0,
            edge_count: 0,
        }
    }

    /// The remembered edges, newest first.
    fn edges(&self) -> &[Edge] {
        self.recent.get(..self.stored).unwrap_or(&self.recent)
    }

    /// The raw count since power-up (no wrap, no preload).
    pub fn count(&self) -> i64 {
        self.count
    }

    /// Total edges seen since power-up.
    pub fn edge_count(&self) -> u64 {
        self.edge_count
    }

    /// Channel A level.
    pub fn a(&self) -> bool {
        matches!(quadrature_state(self.count), 1 | 2)
    }

    /// Channel B level.
    pub fn b(&self) -> bool {
        matches!(quadrature_state(self.count), 2 | 3)
    }

    /// The index pulse: high for one count per revolution.
    pub fn index(&self) -> bool {
        self.count.rem_euclid(i64::from(self.counts_per_rev)) == 0
    }

    /// Move the shaft linearly from `from` to `to` counts during the span
    /// that starts at `start` and lasts `span_ps` picoseconds, recording
    /// every edge crossed with its interpolated time.
    #[inline]
    pub fn track(&mut self, from: f64, to: f64, start: SimTime, span_ps: u64) {
        let target = floor_count(to);
        // Most spans cross no boundary: that check stays in the caller.
        if target != self.count {
            self.record_edges(from, to, target, start, span_ps);
        }
    }

    /// [`track`](Self::track) once the count is known to move to `target`.
    #[inline(never)]
    fn record_edges(&mut self, from: f64, to: f64, target: i64, start: SimTime, span_ps: u64) {
        let up = target > self.count;
        let crossings = self.count.abs_diff(target);
        // Only the last HISTORY edges can be observed; skip the others.
        let kept = crossings.min(HISTORY as u64) as usize;
        self.edge_count = self.edge_count.saturating_add(crossings);
        // The run of same-direction edges, newest first, after these.
        let continues = self.stored > 0 && self.recent[0].up == up;
        self.same = if continues {
            (self.same + kept).min(HISTORY)
        } else {
            kept
        };
        self.stored = (self.stored + kept).min(HISTORY);
        // The count before the first edge kept, and the way it moves.
        let (mut count, step) = if up {
            (target - kept as i64, 1)
        } else {
            (target + kept as i64, -1)
        };
        self.count = target;
        let dx = to - from;
        let per_count = if dx != 0.0 { 1.0 / dx } else { 0.0 };
        for _ in 0..kept {
            // The boundary crossed: count+1 going up, count going down.
            let boundary = if up { count + 1 } else { count };
            let frac = if dx != 0.0 {
                ((boundary as f64 - from) * per_count).clamp(0.0, 1.0)
            } else {
                1.0
            };
            let at = SimTime(start.0.saturating_add((span_ps as f64 * frac) as u64));
            let kind = EdgeKind::of_transition(count, up);
            count += step;
            // The oldest falls off the end (a move of fixed size, no call).
            self.recent.copy_within(..HISTORY - 1, 1);
            self.recent[0] = Edge {
                clock: at.clocks(),
                up,
                kind,
            };
        }
    }

    /// The velocity fields the FPGA would latch at `now`.
    pub fn fields(&self, now: SimTime) -> VelocityFields {
        self.fields_at_clock(now.clocks())
    }

    /// [`fields`](Self::fields) with the system clock counter at that
    /// instant, `now_clk` (a sample of several encoders counts it once).
    pub(crate) fn fields_at_clock(&self, now_clk: u64) -> VelocityFields {
        let edges = self.edges();
        let edge = |i: usize| edges.get(i).copied();
        let Some(e0) = edge(0) else {
            let (run, run_over) = saturate(now_clk);
            return VelocityFields {
                period: PeriodField {
                    clocks: PERIOD_MAX,
                    overflow: true,
                    partial: true,
                    ..PeriodField::default()
                },
                qtr1: QuarterField {
                    clocks: PERIOD_MAX,
                    overflow: true,
                    ..QuarterField::default()
                },
                qtr5: QuarterField {
                    clocks: PERIOD_MAX,
                    overflow: true,
                    ..QuarterField::default()
                },
                run: RunField {
                    clocks: run,
                    overflow: run_over,
                },
            };
        };
        // Consecutive edges, newest first, in the direction of the newest
        // (counted as they are recorded: 1 ..= stored, so every edge the
        // run reaches is stored and its clock is read straight from the
        // array).
        let stored = edges.len();
        let same = self.same.max(1);
        let reversed = same < stored;
        let clock = |i: usize| edges.get(i).map(|e| e.clock);
        // (Indices below 5 here: always stored edges.)
        let run_clock = |i: usize| self.recent.get(i).map_or(e0.clock, |e| e.clock);

        // Latched full-cycle period (or its extrapolation).
        let intervals = same.min(5) - 1;
        let (latched, partial) = match intervals {
            0 => (None, true),
            4 => (Some(e0.clock - run_clock(4)), false),
            k => (Some(quarters_to_cycle(e0.clock - run_clock(k), k)), true),
        };
        // Free-running counter of the next expected edge: it completes a
        // cycle with edge 3 (or an extrapolated one with fewer edges).
        let j = same.min(4) - 1;
        let running = quarters_to_cycle(now_clk.saturating_sub(run_clock(j)), j + 1);
        let period_clocks = match latched {
            Some(l) => l.max(running),
            None => running.max(u64::from(PERIOD_MAX) + 1),
        };
        let (period, period_over) = saturate(period_clocks);
        let error = clock(1).is_some_and(|c1| c1 == e0.clock);

        let quarter = |newer: usize| -> QuarterField {
            match (edge(newer), clock(newer + 1)) {
                (Some(e), Some(older)) => {
                    let (clocks, overflow) = saturate(e.clock - older);
                    QuarterField {
                        clocks,
                        overflow,
                        up: e.up,
                        edge_mask: e.kind.mask(),
                    }
                }
                (Some(e), None) => QuarterField {
                    clocks: PERIOD_MAX,
                    overflow: true,
                    up: e.up,
                    edge_mask: e.kind.mask(),
                },
                _ => QuarterField {
                    clocks: PERIOD_MAX,
                    overflow: true,
                    ..QuarterField::default()
                },
            }
        };
        let (run, run_over) = saturate(now_clk.saturating_sub(e0.clock));
        VelocityFields {
            period: PeriodField {
                clocks: period,
                overflow: period_over,
                up: e0.up,
                direction_changed: reversed && same < 5,
                error,
                partial,
            },
            qtr1: quarter(0),
            qtr5: quarter(4),
            run: RunField {
                clocks: run,
                overflow: run_over,
            },
        }
    }
}

/// Where `count` is in the quadrature cycle, 0..=3: `count.rem_euclid(4)`
/// by a mask (two's complement).
fn quadrature_state(count: i64) -> i64 {
    count & 3
}

fn floor_count(position: f64) -> i64 {
    const LIMIT: f64 = i64::MAX as f64 / 2.0;
    if !position.is_finite() {
        return 0;
    }
    let clamped = position.clamp(-LIMIT, LIMIT);
    // Truncation, then one down for negative fractions: the floor without
    // a call into libm (x86-64's baseline has no rounding instruction).
    let t = clamped as i64;
    if (t as f64) > clamped { t - 1 } else { t }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::time::{PS_PER_S, SYSTEM_CLOCK_HZ};

    /// Constant speed: `counts_per_s` for `seconds`, in 10 us sub-steps.
    fn run(enc: &mut Encoder, start_pos: f64, counts_per_s: f64, seconds: f64) -> (f64, SimTime) {
        let step_ps = 10_000_000u64;
        let steps = (seconds * PS_PER_S as f64 / step_ps as f64) as u64;
        let mut pos = start_pos;
        let mut t = SimTime::ZERO;
        for _ in 0..steps {
            let next = pos + counts_per_s * step_ps as f64 / PS_PER_S as f64;
            enc.track(pos, next, t, step_ps);
            pos = next;
            t = SimTime(t.0 + step_ps);
        }
        (pos, t)
    }

    #[test]
    fn levels_follow_gray_code() {
        let mut enc = Encoder::new(4000, 0.5);
        let mut seen = std::vec::Vec::new();
        for c in 0..8 {
            let from = c as f64 + 0.5;
            enc.track(from, from + 1.0, SimTime::ZERO, 1);
            seen.push((enc.a(), enc.b()));
        }
        // Counts 1..=8: states 1,2,3,0,...: A leads B.
        assert_eq!(
            &seen[..4],
            &[(true, false), (true, true), (false, true), (false, false)]
        );
        assert_eq!(enc.count(), 8);
    }

    #[test]
    fn constant_speed_period_matches() {
        let mut enc = Encoder::new(4000, 0.0);
        // 10_000 counts/s: one quarter = 100 us = 4915.2 clocks.
        let (_, t) = run(&mut enc, 0.5, 10_000.0, 0.01);
        let f = enc.fields(t);
        let cycle = 4.0 * SYSTEM_CLOCK_HZ as f64 / 10_000.0;
        assert!(!f.period.overflow && !f.period.partial && !f.period.direction_changed);
        assert!(f.period.up);
        assert!((f64::from(f.period.clocks) - cycle).abs() <= 2.0, "{f:?}");
        assert!((f64::from(f.qtr1.clocks) - cycle / 4.0).abs() <= 2.0);
        assert!((f64::from(f.qtr5.clocks) - cycle / 4.0).abs() <= 2.0);
        assert_eq!(f.qtr1.edge_mask, f.qtr5.edge_mask);
        assert!(f.run.clocks <= (cycle / 4.0) as u32 + 1);
    }

    #[test]
    fn stopping_grows_period_then_overflows() {
        let mut enc = Encoder::new(4000, 0.0);
        let (pos, t) = run(&mut enc, 0.5, 10_000.0, 0.01);
        let _ = pos;
        let moving = enc.fields(t).period.clocks;
        let later = enc.fields(SimTime(t.0 + PS_PER_S / 100));
        assert!(later.period.clocks > moving);
        let much_later = enc.fields(SimTime(t.0 + 2 * PS_PER_S));
        assert!(much_later.period.overflow && much_later.run.overflow);
        assert_eq!(much_later.run.clocks, PERIOD_MAX);
    }

    #[test]
    fn reversal_sets_direction_changed() {
        let mut enc = Encoder::new(4000, 0.0);
        let (pos, t) = run(&mut enc, 0.5, 10_000.0, 0.01);
        enc.track(pos, pos - 1.0, t, 1_000_000);
        let f = enc.fields(SimTime(t.0 + 1_000_000));
        assert!(!f.period.up && f.period.direction_changed && f.period.partial);
        assert!(!f.qtr1.up);
    }

    #[test]
    fn backwards_counts_down() {
        let mut enc = Encoder::new(4000, 0.0);
        let (_, t) = run(&mut enc, 0.5, -20_000.0, 0.005);
        assert_eq!(enc.count(), -100);
        let f = enc.fields(t);
        assert!(!f.period.up && !f.period.direction_changed);
        let cycle = 4.0 * SYSTEM_CLOCK_HZ as f64 / 20_000.0;
        assert!((f64::from(f.period.clocks) - cycle).abs() <= 2.0);
    }

    #[test]
    fn floor_count_is_the_floor() {
        for x in [
            0.0,
            0.5,
            -0.5,
            -1.0,
            1.0,
            -1.5,
            2.999,
            -2.999,
            1e15 + 0.5,
            -1e15 - 0.5,
        ] {
            assert_eq!(floor_count(x), x.floor() as i64, "{x}");
        }
        assert_eq!(floor_count(f64::NAN), 0);
        assert_eq!(floor_count(f64::INFINITY), 0);
        assert_eq!(floor_count(1e300), (i64::MAX as f64 / 2.0) as i64);
        assert_eq!(floor_count(-1e300), -((i64::MAX as f64 / 2.0) as i64));
    }

    #[test]
    fn each_transition_is_the_edge_its_levels_make() {
        let levels = |c: i64| {
            let enc = Encoder::new(4000, c as f64 + 0.5);
            (enc.a(), enc.b())
        };
        for from in -9..9 {
            for up in [false, true] {
                let to = if up { from + 1 } else { from - 1 };
                let ((a0, b0), (a1, b1)) = (levels(from), levels(to));
                assert!((a0 != a1) != (b0 != b1), "one channel moves");
                let expected = match (a0 != a1, a1, b1) {
                    (true, true, _) => EdgeKind::ARise,
                    (true, false, _) => EdgeKind::AFall,
                    (false, _, true) => EdgeKind::BRise,
                    (false, _, false) => EdgeKind::BFall,
                };
                assert_eq!(EdgeKind::of_transition(from, up), expected, "{from} {up}");
            }
        }
    }

    #[test]
    fn a_span_over_several_edges_keeps_the_last_six_newest_first() {
        // From 2.5 to 11.5 counts (9 edges) and back to 7.25 (4 edges),
        // each over 1 us: every edge at its interpolated time.
        let span = 1_000_000u64;
        let mut enc = Encoder::new(4000, 2.5);
        enc.track(2.5, 11.5, SimTime::ZERO, span);
        assert_eq!((enc.count(), enc.edge_count()), (11, 9));
        let at = |start: u64, from: f64, to: f64, boundary: i64| {
            let frac = ((boundary as f64 - from) * (1.0 / (to - from))).clamp(0.0, 1.0);
            SimTime(start + (span as f64 * frac) as u64).clocks()
        };
        // Newest first: the boundaries 11, 10, ..., 6 crossed going up.
        let up: std::vec::Vec<Edge> = (6..=11)
            .rev()
            .map(|b| Edge {
                clock: at(0, 2.5, 11.5, b),
                up: true,
                kind: EdgeKind::of_transition(b - 1, true),
            })
            .collect();
        assert_eq!(enc.edges(), &up[..]);
        assert_eq!(enc.same, 6);
        enc.track(11.5, 7.25, SimTime(span), span);
        assert_eq!((enc.count(), enc.edge_count()), (7, 13));
        // Down through boundaries 11, 10, 9, 8 (count 11 -> 7), then the
        // two newest of the way up.
        let mut expected: std::vec::Vec<Edge> = (8..=11)
            .map(|b| Edge {
                clock: at(span, 11.5, 7.25, b),
                up: false,
                kind: EdgeKind::of_transition(b, false),
            })
            .collect();
        expected.extend_from_slice(&up[..2]);
        assert_eq!(enc.edges(), &expected[..]);
        assert_eq!((enc.same, enc.stored), (4, 6));
    }

    #[test]
    fn no_edges_is_overflow() {
        let enc = Encoder::new(4000, 0.0);
        let f = enc.fields(SimTime::from_millis(1));
        assert!(f.period.overflow && f.qtr1.overflow && f.qtr5.overflow);
        assert!(!f.run.overflow);
    }
}
