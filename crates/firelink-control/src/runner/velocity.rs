//! Joint velocity from encoder positions over a short window of cycles.
//!
//! One encoder count over a single 6 kHz period reads as metres per second
//! on coarse axes, so the estimate differences positions [`WINDOW`] cycles
//! apart. It divides by the *measured* time between those two samples, not
//! by a nominal or last period: a late cycle (the host stalled, a packet was
//! retried) then changes nothing but the span, and the estimate stays true.

/// Positions are differenced this many cycles apart.
pub const WINDOW: usize = 8;

/// A ring of the last [`WINDOW`] `(time, position)` samples of one joint
/// and a lightly filtered velocity. Allocation-free; time is passed in.
#[derive(Clone, Copy, Debug, Default)]
pub struct VelocityEstimator {
    times: [f64; WINDOW],
    positions: [f64; WINDOW],
    /// Index of the oldest sample (the next one overwritten).
    oldest: usize,
    primed: bool,
    /// The window was filled from one sample (a joint assumed at rest);
    /// the next sample gives the spacing to date those copies with.
    backfill: bool,
    velocity: f64,
}

impl VelocityEstimator {
    /// Forget the history (after a jump in position, e.g. encoder preload):
    /// the next sample restarts the window at velocity 0.
    pub fn reset(&mut self) {
        self.primed = false;
        self.backfill = false;
        self.velocity = 0.0;
    }

    /// Add the sample taken at `time` (seconds, any origin, increasing) and
    /// return the new estimate. A sample whose time does not advance past
    /// the oldest one in the window leaves the estimate unchanged.
    #[inline(always)]
    pub fn update(&mut self, time: f64, position: f64) -> f64 {
        if self.backfill {
            self.date_the_rest_samples(time);
        }
        // (Always `oldest`; the remainder only shows it is in the window.)
        let slot = self.oldest % WINDOW;
        if self.primed {
            let t0 = self.times.get(slot).copied().unwrap_or(time);
            let p0 = self.positions.get(slot).copied().unwrap_or(position);
            let span = time - t0;
            // (Finite and above 0; false for NaN.)
            if span > 0.0 && span <= f64::MAX {
                let v = (position - p0) / span;
                self.velocity += 0.5 * (v - self.velocity);
                // At rest the filter halves towards 0 and sticks at the
                // smallest subnormal (half of it rounds to 0): a joint at
                // rest would carry ±5e-324 rad/s for ever, and every
                // operation on a subnormal costs the CPU a slow assist,
                // every cycle. Below the normal range it is 0.
                if self.velocity.abs() < f64::MIN_POSITIVE {
                    self.velocity = 0.0;
                }
            }
        } else {
            // A joint at rest until now: every slot holds this sample.
            self.times.fill(time);
            self.positions.fill(position);
            self.velocity = 0.0;
            self.primed = true;
            self.backfill = true;
        }
        if let (Some(t), Some(p)) = (self.times.get_mut(slot), self.positions.get_mut(slot)) {
            *t = time;
            *p = position;
        }
        self.oldest = (slot + 1) % WINDOW;
        self.velocity
    }

    /// After priming every slot holds the first sample: the joint is taken
    /// to have rested there for a whole window at the spacing of the first
    /// two samples, so the first estimates divide by a full window's span,
    /// as later ones do, instead of by one period (one encoder count over
    /// one period would read as a large velocity).
    fn date_the_rest_samples(&mut self, time: f64) {
        let newest = (self.oldest + WINDOW - 1) % WINDOW;
        let t_first = self.times.get(newest).copied().unwrap_or(time);
        let spacing = time - t_first;
        if !(spacing > 0.0 && spacing.is_finite()) {
            return;
        }
        for m in 0..WINDOW - 1 {
            if let Some(t) = self.times.get_mut((self.oldest + m) % WINDOW) {
                *t = t_first - (WINDOW - 1 - m) as f64 * spacing;
            }
        }
        self.backfill = false;
    }

    /// The current estimate (0 before the first sample).
    pub fn velocity(&self) -> f64 {
        self.velocity
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Constant velocity sampled at a steady 6 kHz, with one cycle late by
    /// `late` periods: the estimate is the true velocity on every cycle
    /// after the window has filled, late cycle or not.
    fn estimate_with_late_cycle(late: f64) -> Vec<f64> {
        let v = 0.37;
        let period = 1.0 / 6000.0;
        let mut est = VelocityEstimator::default();
        let mut t = 0.0;
        let mut out = Vec::new();
        for k in 0..200 {
            if k == 100 {
                t += late * period;
            }
            out.push(est.update(t, 0.2 + v * t));
            t += period;
        }
        out
    }

    #[test]
    fn a_late_cycle_does_not_inflate_the_estimate() {
        for late in [0.0, 0.5, 3.0, 20.0] {
            let est = estimate_with_late_cycle(late);
            // Filter converged long before cycle 100 and stays on the truth.
            for (k, v) in est.iter().enumerate().skip(60) {
                assert!((v - 0.37).abs() < 1e-9, "late {late}: cycle {k}: {v}");
            }
        }
    }

    /// What the estimate used to do: divide by the nominal period times the
    /// window. One cycle late by 3 periods inflated it by 11/8 for the next
    /// seven cycles; the measured span gives the truth (test above).
    #[test]
    fn the_nominal_period_formula_is_what_went_wrong() {
        let period = 1.0 / 6000.0;
        let span_with_late = (WINDOW as f64 + 3.0) * period;
        let nominal = 0.37 * span_with_late / (WINDOW as f64 * period);
        assert!(nominal > 0.37 * 1.3);
    }

    /// Right after priming, one encoder count over one period is not read
    /// as a velocity of a count per period: the rest samples span a window.
    #[test]
    fn first_estimates_span_a_whole_window() {
        let mut est = VelocityEstimator::default();
        est.update(0.0, 1.0);
        let v = est.update(1e-3, 1.0 + 8e-3);
        // (8e-3 over 8 periods of 1e-3) = 1.0, halved by the filter.
        assert!((v - 0.5).abs() < 1e-9, "{v}");
    }

    /// A joint coming to rest reads exactly 0, not a subnormal the
    /// filter's halving would otherwise stick at.
    #[test]
    fn at_rest_the_estimate_reaches_zero() {
        let mut est = VelocityEstimator::default();
        let period = 1.0 / 6000.0;
        for k in 0..50 {
            est.update(f64::from(k) * period, 0.1 * f64::from(k) * period);
        }
        assert!(est.velocity() > 0.09);
        let mut t = 50.0 * period;
        for _ in 0..3000 {
            let v = est.update(t, 0.5);
            assert!(v == 0.0 || v.abs() >= f64::MIN_POSITIVE, "{v:e}");
            t += period;
        }
        assert_eq!(est.velocity(), 0.0);
    }

    #[test]
    fn first_sample_reads_zero_and_stalled_time_changes_nothing() {
        let mut est = VelocityEstimator::default();
        assert_eq!(est.update(1.0, 5.0), 0.0);
        for k in 1..=WINDOW {
            est.update(1.0 + k as f64 * 1e-3, 5.0 + k as f64 * 2e-3);
        }
        let v = est.velocity();
        assert!(v > 0.0);
        // A repeated timestamp spanning nothing is ignored.
        let mut same = est;
        let t = 1.0 + WINDOW as f64 * 1e-3;
        for _ in 0..WINDOW {
            same.update(t, 99.0);
        }
        assert!(same.velocity().is_finite());
        est.reset();
        assert_eq!(est.velocity(), 0.0);
        assert_eq!(est.update(2.0, 0.0), 0.0);
    }
}
