//! Seed 002's Table III from the simulation: the worst-case time of a read
//! transaction by payload (4 to 496 bytes) under Xenomai and RTLinux, and
//! its distribution over many reads.
//!
//! The rig is the seed's experiment: the computer and one motor controller
//! module on the card's first port. Each read is a block read of the
//! module's trace buffer, timed from the call to its return (the seed's
//! `t1`..`t2`), through everything the simulation has: the computer's
//! real-time system ([`RtosModel`](firelink_host::mahru::rtos::RtosModel),
//! seeded jitter), the request on the wire, the module's DSP noticing it
//! at its next poll and copying the answer out, the response arbitrating
//! for the bus, the computer waking up. The split at the request's ack
//! gives Table IV's request and response times.
//!
//! Points run in parallel (each on its own rig with its own seed), so the
//! result does not depend on the number of threads.

use std::fmt;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use serde::Serialize;

use firelink_board::mahru::{DeviceConfig, JointParams, ModuleConfig, ResponderTiming};
use firelink_host::mahru::rtos::Rtos;
use firelink_host::port::{Dest, Port};
use firelink_wire::mahru::{ModId, TRACE_BUFFER_OFFSET};
use firelink_wire::packet::Speed;

use super::demo::Stat;
use super::rig::{build_bus, sbc_port};
use crate::TestbedError;

/// Table III of seed 002: payload (bytes), Xenomai WCET, RTLinux WCET (us).
pub const PAPER: [(usize, f64, f64); 6] = [
    (4, 61.0, 58.0),
    (32, 75.0, 70.0),
    (64, 90.0, 82.0),
    (128, 118.0, 108.0),
    (256, 172.0, 166.0),
    (496, 277.0, 272.0),
];

/// The seed's figure for `rtos` at `payload` bytes.
pub fn paper_wcet(rtos: Rtos, payload: usize) -> Option<f64> {
    PAPER
        .iter()
        .find(|p| p.0 == payload)
        .map(|p| if rtos == Rtos::Xenomai { p.1 } else { p.2 })
}

/// The most reads per payload and system (each read's times are kept:
/// three series of `f32`).
pub const MAX_READS: u64 = 10_000_000;

/// What to measure.
#[derive(Debug, Clone, PartialEq)]
pub struct Table3Options {
    /// Reads per point (the seed: more than a million).
    pub reads: u64,
    /// Payloads, bytes (whole quadlets, 4 to 2048).
    pub payloads: Vec<usize>,
    /// The real-time systems.
    pub rtos: Vec<Rtos>,
    /// The module's DSP timing.
    pub responder: ResponderTiming,
    /// Seed of the computer's jitter.
    pub seed: u64,
    /// Worker threads (0: as many as the machine has).
    pub threads: usize,
}

impl Default for Table3Options {
    fn default() -> Self {
        Table3Options {
            reads: 1_000_000,
            payloads: PAPER.iter().map(|p| p.0).collect(),
            rtos: Rtos::ALL.to_vec(),
            responder: super::MahruConfig::seed002().responder_timing(),
            seed: 2,
            threads: 0,
        }
    }
}

/// One point: a payload under one system.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Table3Point {
    /// The system.
    pub rtos: &'static str,
    /// Payload, bytes.
    pub payload: usize,
    /// Reads timed.
    pub reads: u64,
    /// Call to return, us.
    pub total: Stat,
    /// Call to the request's ack, us.
    pub request: Stat,
    /// The ack to the return, us.
    pub response: Stat,
    /// The seed's worst case, us, if it gives one for this payload.
    pub paper_wcet_us: Option<f64>,
    /// `(max - paper) / paper`, per cent.
    pub diff_pct: Option<f64>,
}

/// The whole table.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Table3Report {
    /// Reads per point.
    pub reads: u64,
    /// Every point, system by system, payload by payload.
    pub points: Vec<Table3Point>,
}

impl Table3Report {
    /// The point of `rtos` at `payload`.
    pub fn point(&self, rtos: Rtos, payload: usize) -> Option<&Table3Point> {
        self.points
            .iter()
            .find(|p| p.rtos == rtos.name() && p.payload == payload)
    }

    /// The largest difference from the seed's worst cases, per cent.
    pub fn worst_diff_pct(&self) -> f64 {
        self.points
            .iter()
            .filter_map(|p| p.diff_pct)
            .map(f64::abs)
            .fold(0.0, f64::max)
    }
}

/// Time `reads` reads of `payload` bytes under `rtos`.
fn point(rtos: Rtos, payload: usize, options: &Table3Options) -> Result<Table3Point, TestbedError> {
    if payload == 0 || payload % 4 != 0 || payload > firelink_wire::mahru::TRACE_BUFFER_LEN {
        return Err(TestbedError::Config(format!(
            "payload {payload}: whole quadlets, 4 to 2048 bytes"
        )));
    }
    let module = ModuleConfig {
        mod_id: ModId(0),
        name: "module".into(),
        firmware: 2,
        timing: options.responder,
        speed: Speed::S400,
        device: DeviceConfig::Motor(JointParams::default()),
    };
    let b = build_bus(&[vec![module]], options.seed)?;
    let node = b.bus.phy_id(b.modules[0].handle).unwrap_or(0);
    // Each point its own jitter stream.
    let seed = options.seed ^ (payload as u64) << 8 ^ rtos as u64;
    let mut port = sbc_port(b.bus, b.pc, rtos, seed, Speed::S400);
    let n = usize::try_from(options.reads.clamp(1, MAX_READS)).unwrap_or(1);
    let (mut total, mut request, mut response) = (
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::with_capacity(n),
    );
    let mut buf = vec![0u8; payload];
    for _ in 0..n {
        port.read_block(Dest::node(node), TRACE_BUFFER_OFFSET, &mut buf)?;
        let Some(c) = port.last_call() else { continue };
        let acked = c.acked.unwrap_or(c.returned);
        let f = |a: firelink_bus::SimTime, b: firelink_bus::SimTime| {
            b.saturating_since(a).as_micros_f64() as f32
        };
        total.push(f(c.called, c.returned));
        request.push(f(c.called, acked));
        response.push(f(acked, c.returned));
    }
    let total = Stat::of(&mut total);
    let paper = paper_wcet(rtos, payload);
    Ok(Table3Point {
        rtos: rtos.name(),
        payload,
        reads: n as u64,
        request: Stat::of(&mut request),
        response: Stat::of(&mut response),
        paper_wcet_us: paper,
        diff_pct: paper.map(|p| ((total.max - p) / p * 1000.0).round() / 10.0),
        total,
    })
}

/// Run the table; `progress` hears of each point as it finishes.
///
/// # Errors
/// A payload that is not whole quadlets of 4 to 2048 bytes; reads not in
/// `1..=`[`MAX_READS`]; a read that fails.
pub fn run_table3(
    options: &Table3Options,
    progress: impl Fn(&Table3Point) + Sync,
) -> Result<Table3Report, TestbedError> {
    if !(1..=MAX_READS).contains(&options.reads) {
        return Err(TestbedError::Config(format!(
            "Table III: {} reads per payload is out of range: 1 to {MAX_READS}",
            options.reads
        )));
    }
    let jobs: Vec<(Rtos, usize)> = options
        .rtos
        .iter()
        .flat_map(|&r| options.payloads.iter().map(move |&p| (r, p)))
        .collect();
    let threads = match options.threads {
        0 => std::thread::available_parallelism().map_or(1, usize::from),
        n => n,
    }
    .min(jobs.len())
    .max(1);
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<Result<Table3Point, TestbedError>>>> =
        Mutex::new((0..jobs.len()).map(|_| None).collect());
    std::thread::scope(|s| {
        for _ in 0..threads {
            s.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    let Some(&(rtos, payload)) = jobs.get(i) else {
                        break;
                    };
                    let r = point(rtos, payload, options);
                    if let Ok(p) = &r {
                        progress(p);
                    }
                    if let Ok(mut all) = results.lock() {
                        if let Some(slot) = all.get_mut(i) {
                            *slot = Some(r);
                        }
                    }
                }
            });
        }
    });
    let results = results
        .into_inner()
        .map_err(|_| TestbedError::Config("Table III: a worker failed".into()))?;
    let mut points = Vec::with_capacity(jobs.len());
    for r in results {
        match r {
            Some(r) => points.push(r?),
            None => {
                return Err(TestbedError::Config(
                    "Table III: a point did not run".into(),
                ));
            }
        }
    }
    Ok(Table3Report {
        reads: options.reads,
        points,
    })
}

impl fmt::Display for Table3Report {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "Table III: read transaction by payload, {} simulated reads per point (us)",
            self.reads
        )?;
        writeln!(
            f,
            "{:8} {:>7} {:>9} {:>9} {:>9} {:>9} {:>8}   request max  response max",
            "rtos", "payload", "p50", "p99", "max", "paper", "diff"
        )?;
        for p in &self.points {
            writeln!(
                f,
                "{:8} {:>7} {:>9.1} {:>9.1} {:>9.1} {:>9} {:>8}   {:>11.1}  {:>12.1}",
                p.rtos,
                p.payload,
                p.total.p50,
                p.total.p99,
                p.total.max,
                p.paper_wcet_us.map_or("-".into(), |x| format!("{x:.0}")),
                p.diff_pct.map_or("-".into(), |x| format!("{x:+.1} %")),
                p.request.max,
                p.response.max
            )?;
        }
        Ok(())
    }
}
