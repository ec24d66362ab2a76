//! Seeded, counter-addressed measurement noise.
//!
//! Each noise value is a pure function of (seed, axis, channel, sample
//! index): the sample index addresses a SplitMix64 sequence whose start
//! is derived from the seed and the (axis, channel) stream, and two of its
//! outputs make a normal value (Box-Muller). So a reading does not depend
//! on how often or in which order anything was read before, and the same
//! seed gives the same run bit for bit. A value costs a few multiplications:
//! the emulated boards draw one per axis at every 100 us safety tick and
//! every read block.

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

/// SplitMix64's increment (2^64 / golden ratio).
const GAMMA: u64 = 0x9E37_79B9_7F4A_7C15;

/// SplitMix64's output function: a bijective 64-bit mixer.
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The noise generator of one plant.
#[derive(Debug, Clone)]
pub struct Noise {
    seed: u64,
}

impl Noise {
    /// A generator for `seed`.
    pub fn new(seed: u64) -> Noise {
        Noise { seed: mix(seed) }
    }

    /// A standard normal value for (axis, channel, sample).
    pub fn gaussian(&self, axis: usize, channel: NoiseChannel, sample: u64) -> f64 {
        let stream = ((axis as u64) << 8) | channel as u64;
        let start = mix(self.seed ^ mix(stream.wrapping_add(GAMMA)));
        let at = |k: u64| mix(start.wrapping_add(k.wrapping_mul(GAMMA)));
        let k = sample.wrapping_mul(2);
        // Box-Muller; u1 in (0, 1] so the logarithm is finite.
        let u1 = ((at(k) >> 11) as f64 + 1.0) / (1u64 << 53) as f64;
        let u2 = (at(k.wrapping_add(1)) >> 11) as f64 / (1u64 << 53) as f64;
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

    #[test]
    fn samples_and_streams_are_uncorrelated_with_normal_tails() {
        let g = Noise::new(3);
        let n = 20_000u64;
        let a: Vec<f64> = (0..n)
            .map(|i| g.gaussian(2, NoiseChannel::Pot, i))
            .collect();
        let b: Vec<f64> = (0..n)
            .map(|i| g.gaussian(3, NoiseChannel::Pot, i))
            .collect();
        let c: Vec<f64> = (0..n)
            .map(|i| g.gaussian(2, NoiseChannel::Current, i))
            .collect();
        let corr = |x: &[f64], y: &[f64]| {
            let m = x.len() as f64;
            let (mx, my) = (x.iter().sum::<f64>() / m, y.iter().sum::<f64>() / m);
            let cov: f64 = x.iter().zip(y).map(|(p, q)| (p - mx) * (q - my)).sum();
            let vx: f64 = x.iter().map(|p| (p - mx) * (p - mx)).sum();
            let vy: f64 = y.iter().map(|q| (q - my) * (q - my)).sum();
            cov / (vx * vy).sqrt()
        };
        // 4 sigma of a sample correlation over 20000 values is 0.028.
        assert!(corr(&a[1..], &a[..a.len() - 1]).abs() < 0.03, "lag 1");
        assert!(corr(&a, &b).abs() < 0.03, "axes");
        assert!(corr(&a, &c).abs() < 0.03, "channels");
        let tails = a.iter().filter(|x| x.abs() > 2.0).count() as f64 / n as f64;
        assert!((tails - 0.0455).abs() < 0.006, "{tails}");
    }
}
