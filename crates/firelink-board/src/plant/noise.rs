//! Seeded, counter-addressed measurement noise.
//!
//! Each noise value is a pure function of (seed, axis, channel, sample
//! index): a ChaCha8 stream chosen by axis and channel, positioned at the
//! sample index. So a reading does not depend on how often or in which
//! order anything was read before, and the same seed gives the same run
//! bit for bit.

use rand::{RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Which measurement a noise value perturbs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NoiseChannel {
    /// Motor current sense.
    Current = 0,
    /// Potentiometer.
    Pot = 1,
    /// A force/torque sensor's strain gauges (the axis picks the gauge).
    ForceTorque = 2,
}

/// The noise generator of one plant.
#[derive(Debug, Clone)]
pub struct Noise {
    base: ChaCha8Rng,
}

impl Noise {
    /// A generator for `seed`.
    pub fn new(seed: u64) -> Noise {
        Noise {
            base: ChaCha8Rng::seed_from_u64(seed),
        }
    }

    /// A standard normal value for (axis, channel, sample).
    pub fn gaussian(&self, axis: usize, channel: NoiseChannel, sample: u64) -> f64 {
        let mut rng = self.base.clone();
        rng.set_stream(((axis as u64) << 8) | channel as u64);
        // Two u64 per sample = four 32-bit words.
        rng.set_word_pos(u128::from(sample) * 4);
        // Box-Muller; u1 in (0, 1] so the logarithm is finite.
        let u1 = ((rng.next_u64() >> 11) as f64 + 1.0) / (1u64 << 53) as f64;
        let u2 = (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
        (-2.0 * u1.ln()).sqrt() * (2.0 * core::f64::consts::PI * u2).cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deterministic_and_roughly_normal() {
        let a = Noise::new(7);
        let b = Noise::new(7);
        let c = Noise::new(8);
        assert_eq!(
            a.gaussian(1, NoiseChannel::Current, 42),
            b.gaussian(1, NoiseChannel::Current, 42)
        );
        assert_ne!(
            a.gaussian(1, NoiseChannel::Current, 42),
            c.gaussian(1, NoiseChannel::Current, 42)
        );
        assert_ne!(
            a.gaussian(1, NoiseChannel::Current, 42),
            a.gaussian(1, NoiseChannel::Pot, 42)
        );
        let n = 4000;
        let xs: std::vec::Vec<f64> = (0..n)
            .map(|i| a.gaussian(0, NoiseChannel::Current, i))
            .collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let var = xs.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / n as f64;
        assert!(mean.abs() < 0.1, "{mean}");
        assert!((var - 1.0).abs() < 0.1, "{var}");
    }
}
