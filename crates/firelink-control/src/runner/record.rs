//! What the runner records: per-arm tracking errors ([`ArmTracking`]) and
//! the per-cycle timing record ([`CycleTimes`], summarised by
//! [`Percentiles`]).

use std::time::Duration;

/// Tracking error of one arm, over the cycles it was Active with a motion.
#[derive(Debug, Clone, PartialEq)]
pub struct ArmTracking {
    /// Robot name from the configuration.
    pub name: String,
    /// Revolute joints: RMS error, radians.
    pub rms_rad: f64,
    /// Revolute joints: largest |error|, radians.
    pub max_rad: f64,
    /// Prismatic joints: RMS error, millimetres (0 without any).
    pub rms_mm: f64,
    /// Prismatic joints: largest |error|, millimetres.
    pub max_mm: f64,
    /// Joint samples taken.
    pub samples: u64,
}

/// Running tracking-error sums of one arm.
#[derive(Debug, Clone, Default)]
pub(crate) struct ArmAcc {
    sum_rad: f64,
    n_rad: u64,
    max_rad: f64,
    sum_m: f64,
    n_m: u64,
    max_m: f64,
}

impl ArmAcc {
    /// Add one joint's |setpoint - position|.
    #[inline]
    pub(crate) fn add(&mut self, err: f64, prismatic: bool) {
        if prismatic {
            self.sum_m += err * err;
            self.n_m += 1;
            self.max_m = self.max_m.max(err);
        } else {
            self.sum_rad += err * err;
            self.n_rad += 1;
            self.max_rad = self.max_rad.max(err);
        }
    }

    /// The arm's tracking so far.
    pub(crate) fn tracking(&self, name: &str) -> ArmTracking {
        ArmTracking {
            name: name.to_string(),
            rms_rad: if self.n_rad > 0 {
                (self.sum_rad / self.n_rad as f64).sqrt()
            } else {
                0.0
            },
            max_rad: self.max_rad,
            rms_mm: if self.n_m > 0 {
                1e3 * (self.sum_m / self.n_m as f64).sqrt()
            } else {
                0.0
            },
            max_mm: 1e3 * self.max_m,
            samples: self.n_rad + self.n_m,
        }
    }
}

/// Median, p90, p99 and max of a set of durations, microseconds.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Percentiles {
    /// Median.
    pub median: f64,
    /// 90th percentile (with the median and p99: the shape of the
    /// distribution, e.g. two modes).
    pub p90: f64,
    /// 99th percentile.
    pub p99: f64,
    /// Maximum.
    pub max: f64,
    /// Mean.
    pub mean: f64,
}

impl Percentiles {
    /// From samples (sorted in place).
    pub fn of(samples: &mut [f32]) -> Percentiles {
        if samples.is_empty() {
            return Percentiles::default();
        }
        samples.sort_by(f32::total_cmp);
        let at = |q: f64| {
            let i = ((samples.len() - 1) as f64 * q).round() as usize;
            f64::from(samples.get(i).copied().unwrap_or(0.0))
        };
        let mean = samples.iter().map(|&x| f64::from(x)).sum::<f64>() / samples.len() as f64;
        Percentiles {
            median: at(0.5),
            p90: at(0.9),
            p99: at(0.99),
            max: at(1.0),
            mean,
        }
    }
}

/// Timing record of the cycles run.
#[derive(Debug, Clone, Default)]
pub struct CycleTimes {
    /// I/O time per cycle (read + write phases on the port's clock), us.
    pub io_us: Vec<f32>,
    /// Compute time per cycle (machine clock), us.
    pub compute_us: Vec<f32>,
    /// Cycle time = I/O + compute, us.
    pub cycle_us: Vec<f32>,
    /// Cycles not recorded (record full).
    pub dropped: u64,
    /// Wall-clock pacing: cycles that started after their deadline.
    pub overruns: u64,
    /// Compute time of the last cycle, us (kept when the record is full).
    pub last_compute_us: f32,
}

impl CycleTimes {
    /// An empty record with room for `cap` cycles.
    pub(crate) fn with_capacity(cap: usize) -> CycleTimes {
        CycleTimes {
            io_us: Vec::with_capacity(cap),
            compute_us: Vec::with_capacity(cap),
            cycle_us: Vec::with_capacity(cap),
            dropped: 0,
            overruns: 0,
            last_compute_us: 0.0,
        }
    }

    /// Record one cycle (allocation-free: beyond the capacity it is only
    /// counted).
    #[inline]
    pub(crate) fn record(&mut self, io: Duration, compute: Duration) {
        let io_us = io.as_secs_f64() * 1e6;
        let c_us = compute.as_secs_f64() * 1e6;
        self.last_compute_us = c_us as f32;
        if self.io_us.len() < self.io_us.capacity() {
            self.io_us.push(io_us as f32);
            self.compute_us.push(c_us as f32);
            self.cycle_us.push((io_us + c_us) as f32);
        } else {
            self.dropped += 1;
        }
    }
}
