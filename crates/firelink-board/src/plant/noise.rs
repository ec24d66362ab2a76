//! Seeded, counter-addressed measurement noise.
//!
//! Each noise value is a pure function of (seed, axis, channel, sample
//! index): the sample index addresses a SplitMix64 sequence whose start
//! is derived from the seed and the (axis, channel) stream, and one of its
//! outputs, a uniform value, goes through the inverse of the normal
//! distribution (Acklam's rational approximation, within 1.2e-9 of it
//! everywhere). So a reading does not depend on how often or in which
//! order anything was read before, and the same seed gives the same run
//! bit for bit. A value costs a few multiplications and one division (a
//! logarithm and a square root in the outer 4.85 %): the emulated boards
//! draw one per axis at every 100 us safety tick and every read block.

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

/// No value this generator draws is further from 0 than this (the
/// quantile of the most extreme uniform it uses, 2^-53, is about 8.2): a
/// reading can be known within `MAX_DEVIATE` standard deviations without
/// drawing its noise.
pub const MAX_DEVIATE: f64 = 8.5;

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
        self.stream(axis, channel).gaussian(sample)
    }

    /// The stream of (axis, channel): the same values as
    /// [`gaussian`](Self::gaussian), its start worked out once.
    pub fn stream(&self, axis: usize, channel: NoiseChannel) -> NoiseStream {
        let stream = ((axis as u64) << 8) | channel as u64;
        NoiseStream {
            start: mix(self.seed ^ mix(stream.wrapping_add(GAMMA))),
        }
    }
}

/// One (axis, channel) stream of a [`Noise`] generator.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NoiseStream {
    start: u64,
}

impl NoiseStream {
    /// The standard normal value of sample `sample`.
    pub fn gaussian(&self, sample: u64) -> f64 {
        let bits = mix(self.start.wrapping_add(sample.wrapping_mul(GAMMA)));
        // Uniform in (0, 1) on the grid (k + 1/2) / 2^52: never 0 or 1 (so
        // the tails stay finite), and exact (52 bits and a half fit the
        // mantissa; so does 1 - p).
        let p = ((bits >> 12) as f64 + 0.5) / (1u64 << 52) as f64;
        inverse_normal(p)
    }
}

/// The standard normal quantile of `p` in (0, 1), by Peter J. Acklam's
/// rational approximations (relative error below 1.15e-9): one rational
/// function in the central region, another of `sqrt(-2 ln p)` in the
/// tails.
fn inverse_normal(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    const LOW: f64 = 0.02425;
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < LOW {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - LOW {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
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
    fn the_quantile_matches_known_values() {
        // Standard normal quantiles (tables): the approximation's stated
        // accuracy, at the centre, the region boundary and in the tails.
        for (p, z) in [
            (0.5, 0.0),
            (0.975, 1.959_963_984_540_054),
            (0.02425, -1.972_961_051_311_884_5),
            (0.001, -3.090_232_306_167_813),
            (1e-9, -5.997_807_015_007_687),
        ] {
            let x = inverse_normal(p);
            assert!(
                (x - z).abs() <= 1.2e-9 * z.abs().max(1.0),
                "{p}: {x} vs {z}"
            );
            assert!((inverse_normal(1.0 - p) + z).abs() <= 1.2e-9 * z.abs().max(1.0));
        }
        // The extremes the generator can draw stay finite, and within
        // MAX_DEVIATE.
        let tiny = 0.5 / (1u64 << 52) as f64;
        assert!(1.0 - tiny < 1.0);
        assert!(inverse_normal(tiny).abs() < MAX_DEVIATE);
        assert!(inverse_normal(1.0 - tiny).abs() < MAX_DEVIATE);
        assert!(inverse_normal(tiny).is_finite() && inverse_normal(1.0 - tiny).is_finite());
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
