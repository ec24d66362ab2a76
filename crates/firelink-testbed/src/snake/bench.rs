//! Seed 001's measurements (§8, Fig. 20 and 21) reproduced on the
//! simulated bus: one Snake node at S400 behind a PC whose software
//! overhead is seed 001's machine's ([`HostModel::seed001`], with the
//! bands of Fig. 20 and the noise of Fig. 21 as its spread, seeded).
//!
//! - quadlet read and write times over 9000 iterations each (Fig. 20);
//! - block reads and writes over the whole range of sizes, 1 to 512
//!   quadlets: the base latency and the speed from a straight-line fit
//!   (Fig. 21);
//! - the two servo budgets of §8.2 and §8.4: a read-control-write cycle
//!   for seven axes with one quadlet read and one quadlet write per axis
//!   (the seed's 453 us), and with one block read and one block write
//!   (the seed's 65 us).
//!
//! Every figure is compared with the paper's and must lie within
//! [`TOLERANCE_PERCENT`]. The measurement reads the port's virtual clock:
//! the same seed gives the same report.
//!
//! [`HostModel::seed001`]: firelink_bus::HostModel::seed001

use std::fmt;

use serde::Serialize;

use firelink_board::snake::SnakeNodeConfig;
use firelink_host::{Dest, Port};
use firelink_wire::snake::address::{ChannelDevice, GlobalRegister, SnakeRegister};
use firelink_wire::snake::block::{READ_BLOCK_QUADLETS, WRITE_BLOCK_QUADLETS};
use firelink_wire::snake::registers::{DAC_MIDPOINT, DacCommand, PowerControl};
use firelink_wire::snake::{BLOCK_OFFSET, CHANNELS, MAX_BLOCK_QUADLETS};

use crate::TestbedError;
use crate::snake::sim_port;

/// How close every figure must come to the paper's.
pub const TOLERANCE_PERCENT: f64 = 15.0;

/// What to measure.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Seed001Options {
    /// Quadlet reads and writes, each (the paper: 9000).
    pub iterations: usize,
    /// Block sizes every this many quadlets from 1 to 512.
    pub sweep_step: usize,
    /// Transactions per block size.
    pub sweep_repeats: usize,
    /// Servo cycles of each budget measurement.
    pub cycles: usize,
    /// Seed of the PC model's spread.
    pub seed: u64,
}

impl Default for Seed001Options {
    fn default() -> Self {
        Seed001Options {
            iterations: 9000,
            sweep_step: 1,
            sweep_repeats: 4,
            cycles: 1000,
            seed: 1,
        }
    }
}

/// One compared figure.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Row {
    /// What it is.
    pub quantity: &'static str,
    /// The seed's figure.
    pub paper: f64,
    /// Measured on the simulated bus.
    pub simulated: f64,
    /// Unit of both.
    pub unit: &'static str,
    /// (simulated - paper) / paper, percent.
    pub difference_percent: f64,
    /// Within [`TOLERANCE_PERCENT`].
    pub within_tolerance: bool,
}

/// Mean transaction time of one block size.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SweepPoint {
    /// Quadlets moved.
    pub quadlets: usize,
    /// Mean time of one transaction, us.
    pub mean_us: f64,
}

/// A straight line through a sweep.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LineFit {
    /// Time at zero quadlets: the base latency, us.
    pub base_us: f64,
    /// Time per quadlet, us.
    pub us_per_quadlet: f64,
    /// The speed that slope means: 32 bits per `us_per_quadlet`, Mb/s.
    pub mbps: f64,
}

impl LineFit {
    /// Least squares through `points`.
    pub fn of(points: &[SweepPoint]) -> LineFit {
        let n = points.len() as f64;
        let (sx, sy) = points.iter().fold((0.0, 0.0), |(sx, sy), p| {
            (sx + p.quadlets as f64, sy + p.mean_us)
        });
        let (mx, my) = if n > 0.0 {
            (sx / n, sy / n)
        } else {
            (0.0, 0.0)
        };
        let (sxy, sxx) = points.iter().fold((0.0, 0.0), |(sxy, sxx), p| {
            let dx = p.quadlets as f64 - mx;
            (sxy + dx * (p.mean_us - my), sxx + dx * dx)
        });
        let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
        LineFit {
            base_us: my - slope * mx,
            us_per_quadlet: slope,
            mbps: if slope > 0.0 { 32.0 / slope } else { 0.0 },
        }
    }
}

/// What the reproduction measured; serialises to `firelink bench --seed
/// 001 --json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Seed001Report {
    /// The setup, in words.
    pub setup: String,
    /// The options used.
    pub iterations: usize,
    /// Every compared figure.
    pub rows: Vec<Row>,
    /// Fig. 20: every quadlet read's time, in order, us.
    pub quadlet_read_us: Vec<f32>,
    /// Fig. 20: every quadlet write's time, in order, us.
    pub quadlet_write_us: Vec<f32>,
    /// Fig. 21: mean block read time per size.
    pub block_read: Vec<SweepPoint>,
    /// Fig. 21: mean block write time per size.
    pub block_write: Vec<SweepPoint>,
    /// The fit through the block reads.
    pub block_read_fit: LineFit,
    /// The fit through the block writes.
    pub block_write_fit: LineFit,
    /// Tolerance of every row, percent.
    pub tolerance_percent: f64,
}

impl Seed001Report {
    /// Whether every figure is within the tolerance; the error names the
    /// ones that are not.
    ///
    /// # Errors
    /// The rows outside the tolerance.
    pub fn verdict(&self) -> Result<(), String> {
        let off: Vec<String> = self
            .rows
            .iter()
            .filter(|r| !r.within_tolerance)
            .map(|r| format!("{} {:+.1} %", r.quantity, r.difference_percent))
            .collect();
        if off.is_empty() {
            Ok(())
        } else {
            Err(format!(
                "outside {} % of seed 001: {}",
                self.tolerance_percent,
                off.join(", ")
            ))
        }
    }
}

impl fmt::Display for Seed001Report {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "Seed 001 measurements reproduced ({})", self.setup)?;
        writeln!(
            f,
            "  {:<44} {:>10} {:>10} {:>6}  {:>7}",
            "quantity", "paper", "simulated", "unit", "diff"
        )?;
        for r in &self.rows {
            writeln!(
                f,
                "  {:<44} {:>10.1} {:>10.1} {:>6}  {:>+6.1} %{}",
                r.quantity,
                r.paper,
                r.simulated,
                r.unit,
                r.difference_percent,
                if r.within_tolerance { "" } else { "  OUT" }
            )?;
        }
        Ok(())
    }
}

fn row(quantity: &'static str, paper: f64, simulated: f64, unit: &'static str) -> Row {
    let difference_percent = 100.0 * (simulated - paper) / paper;
    Row {
        quantity,
        paper,
        simulated,
        unit,
        difference_percent,
        within_tolerance: difference_percent.abs() <= TOLERANCE_PERCENT,
    }
}

/// Time one call on the port's clock, us.
fn timed<P: Port>(
    port: &mut P,
    call: impl FnOnce(&mut P) -> firelink_host::Result<()>,
) -> Result<f64, TestbedError> {
    let t0 = port.now();
    call(port)?;
    Ok(port.now().saturating_sub(t0).as_secs_f64() * 1e6)
}

fn mean(xs: &[f32]) -> f64 {
    if xs.is_empty() {
        return 0.0;
    }
    xs.iter().map(|&x| f64::from(x)).sum::<f64>() / xs.len() as f64
}

/// Run the reproduction.
///
/// # Errors
/// [`TestbedError::Config`] for options that measure nothing; a failed
/// transaction (there should be none).
pub fn run_seed001_bench(options: &Seed001Options) -> Result<Seed001Report, TestbedError> {
    if options.iterations == 0 || options.sweep_repeats == 0 || options.cycles == 0 {
        return Err(TestbedError::Config(
            "iterations, repeats and cycles must each be at least 1".into(),
        ));
    }
    if !(1..=MAX_BLOCK_QUADLETS).contains(&options.sweep_step) {
        return Err(TestbedError::Config(format!(
            "sweep step {}: 1 to {MAX_BLOCK_QUADLETS} quadlets",
            options.sweep_step
        )));
    }
    let mut port = sim_port(vec![SnakeNodeConfig::new(0)], true, Some(options.seed))?;
    let node = Dest::node(0);
    let status = SnakeRegister::Global(GlobalRegister::Status).offset();
    // Fig. 20: quadlet reads and writes (a write of STATUS with an empty
    // mask changes nothing).
    let mut reads = Vec::with_capacity(options.iterations);
    let mut writes = Vec::with_capacity(options.iterations);
    for _ in 0..options.iterations {
        reads.push(timed(&mut port, |p| p.read_quadlet(node, status).map(|_| ()))? as f32);
    }
    let no_change = PowerControl::default().raw();
    for _ in 0..options.iterations {
        writes.push(timed(&mut port, |p| p.write_quadlet(node, status, no_change))? as f32);
    }
    // Fig. 21: every block size (the node serves reads of any size and
    // acknowledges writes of any size).
    let sizes: Vec<usize> = (1..=MAX_BLOCK_QUADLETS)
        .step_by(options.sweep_step)
        .collect();
    let mut buf = vec![0u8; 4 * MAX_BLOCK_QUADLETS];
    let zeros = vec![0u8; 4 * MAX_BLOCK_QUADLETS];
    let mut block_read = Vec::with_capacity(sizes.len());
    let mut block_write = Vec::with_capacity(sizes.len());
    for &n in &sizes {
        let (mut r, mut w) = (0.0, 0.0);
        for _ in 0..options.sweep_repeats {
            let out = &mut buf[..4 * n];
            r += timed(&mut port, |p| p.read_block(node, BLOCK_OFFSET, out))?;
            let data = &zeros[..4 * n];
            w += timed(&mut port, |p| p.write_block(node, BLOCK_OFFSET, data))?;
        }
        let k = options.sweep_repeats as f64;
        block_read.push(SweepPoint {
            quadlets: n,
            mean_us: r / k,
        });
        block_write.push(SweepPoint {
            quadlets: n,
            mean_us: w / k,
        });
    }
    let read_fit = LineFit::of(&block_read);
    let write_fit = LineFit::of(&block_write);
    // The budgets: read-control-write for seven axes, by quadlets and by
    // blocks.
    let midpoint = DacCommand::MotorVoltage(DAC_MIDPOINT).to_word();
    let mut quadlet_cycle = 0.0;
    for _ in 0..options.cycles {
        quadlet_cycle += timed(&mut port, |p| {
            for ch in 1..=CHANNELS as u8 {
                let adc = SnakeRegister::Channel {
                    channel: ch,
                    device: ChannelDevice::Adc,
                };
                let dac = SnakeRegister::Channel {
                    channel: ch,
                    device: ChannelDevice::Dac,
                };
                p.read_quadlet(node, adc.offset())?;
                p.write_quadlet(node, dac.offset(), midpoint)?;
            }
            Ok(())
        })?;
    }
    let mut block_cycle = 0.0;
    for _ in 0..options.cycles {
        let out = &mut buf[..4 * READ_BLOCK_QUADLETS];
        block_cycle += timed(&mut port, |p| p.read_block(node, BLOCK_OFFSET, out))?;
        let data = &zeros[..4 * WRITE_BLOCK_QUADLETS];
        block_cycle += timed(&mut port, |p| p.write_block(node, BLOCK_OFFSET, data))?;
    }
    let cycles = options.cycles as f64;
    let rows = vec![
        row("quadlet read, mean (Fig. 20)", 34.5, mean(&reads), "us"),
        row("quadlet write, mean (Fig. 20)", 30.2, mean(&writes), "us"),
        row(
            "block read, base latency (Fig. 21)",
            33.2,
            read_fit.base_us,
            "us",
        ),
        row(
            "block write, base latency (Fig. 21)",
            30.7,
            write_fit.base_us,
            "us",
        ),
        row(
            "block read, speed to 512 quadlets (Fig. 21)",
            360.0,
            read_fit.mbps,
            "Mb/s",
        ),
        row(
            "block write, speed to 512 quadlets (Fig. 21)",
            290.0,
            write_fit.mbps,
            "Mb/s",
        ),
        row(
            "7 axes by quadlets: read + write (§8.2)",
            453.0,
            quadlet_cycle / cycles,
            "us",
        ),
        row(
            "7 axes by blocks: read + write (§8.4)",
            65.0,
            block_cycle / cycles,
            "us",
        ),
    ];
    Ok(Seed001Report {
        setup: format!(
            "one Snake node at S400 on the simulated bus; seed 001's PC model \
             (2 GHz Pentium 4, Linux) with its spread, seed {}",
            options.seed
        ),
        iterations: options.iterations,
        rows,
        quadlet_read_us: reads,
        quadlet_write_us: writes,
        block_read,
        block_write,
        block_read_fit: read_fit,
        block_write_fit: write_fit,
        tolerance_percent: TOLERANCE_PERCENT,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_fit() {
        let pts: Vec<SweepPoint> = (1..=10)
            .map(|n| SweepPoint {
                quadlets: n,
                mean_us: 30.0 + 0.1 * n as f64,
            })
            .collect();
        let f = LineFit::of(&pts);
        assert!((f.base_us - 30.0).abs() < 1e-9);
        assert!((f.mbps - 320.0).abs() < 1e-6);
        assert_eq!(LineFit::of(&[]).mbps, 0.0);
    }
}
