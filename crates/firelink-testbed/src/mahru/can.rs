//! Seed 002's Table IV from two models: the same 14-module cycle on a CAN
//! 2.0A bus at 1 Mb/s and on the simulated 1394 bus, side by side, and the
//! seed's 170-180x ratio explained.
//!
//! # The CAN cycle
//! The computer and the 14 modules on one CAN bus ([`firelink_can`]),
//! carrying exactly what the 1394 cycle carries:
//! - **receive** (the 1394 cycle's reads): the computer sends a SYNC frame
//!   (identifier 0x080, no data); every module answers with its block cut
//!   into 8-byte frames: a motor controller its 32-byte joint block (4
//!   frames, identifiers `0x300 + 4 ModID + k`), a sensor its 24-byte
//!   force/torque block (3 frames, `0x380 + 3 i + k`). Each module's DSP
//!   needs its fixed time and polling delay before the first frame and
//!   its per-byte time for each frame, as on 1394. All 14 modules answer
//!   at once; arbitration by identifier orders the 52 frames.
//! - **send** (the 1394 cycle's QWRITE): the computer sends the 10 set-point
//!   slots, 32 bytes each, as 40 frames (`0x200 + 4 ModID + k`).
//!
//! The frames carry the real encodings of walking data (joint blocks, F/T
//! blocks, set-point slots), so their stuff bits are those of real
//! traffic. Send time is the computer's frames (SYNC and set-points), from
//! the first one's start to the last one's end; receive time from the SYNC
//! to the last module frame. The seed's CAN row (4000 / 6500 / 10500 us)
//! comes from another humanoid's CAN system at 1 Mb/s with 8-byte frames
//! (its reference \[16\]); the model explains its size: a cycle of this
//! robot's data needs about 93 frames of 110-135 bits.
//!
//! # The ratio
//! The seed's 181x (RTLinux) and 172x (Xenomai) divide that *whole CAN
//! exchange* by *one* 1394 read transaction (58 / 61 us, the 4-byte row of
//! Table III). The report puts the model's figures beside them and adds the
//! like-for-like ratios: a whole cycle against a whole cycle, with and
//! without the computer's software.

use std::fmt;
use std::time::Duration;

use serde::Serialize;

use firelink_bus::BusTiming;
use firelink_can::bus::{CanBus, CanConfig, Delivery, Outcome};
use firelink_can::frame::{CanId, Frame, worst_case_bits};
use firelink_host::mahru::rtos::Rtos;
use firelink_wire::mahru::{FtBlock, JointBlock, ModId, ModuleKind, ModuleState, SetpointSlot};
use firelink_wire::packet::Speed;

use super::config::MahruConfig;
use super::demo::{PhaseSamples, Stat, bring_up, motion};
use super::gait::Gait;
use super::main_loop::MainLoop;
use super::rig::build_bus;
use super::table3::{Table3Options, run_table3};
use crate::TestbedError;

/// The seed's Table IV: send/request, receive/response, total (us).
pub const PAPER_CAN: [f64; 3] = [4000.0, 6500.0, 10500.0];
/// The seed's Table IV rows for 1394: RTLinux and Xenomai.
pub const PAPER_1394: [(Rtos, [f64; 3]); 2] = [
    (Rtos::RtLinux, [27.0, 31.0, 58.0]),
    (Rtos::Xenomai, [29.0, 32.0, 61.0]),
];

/// The most CAN cycles a run times (each one's three times are kept).
pub const MAX_CAN_CYCLES: u32 = 1_000_000;

/// The most 1394 periods walked per system (each one's I/O time is kept).
pub const MAX_PERIODS: u64 = 10_000_000;

/// What to run.
#[derive(Debug, Clone, PartialEq)]
pub struct Table4Options {
    /// The robot.
    pub config: MahruConfig,
    /// CAN cycles (walking data at successive periods).
    pub cycles: u32,
    /// Chance of a bit error per CAN frame.
    pub error_probability: f64,
    /// 4-byte 1394 reads timed per system.
    pub reads: u64,
    /// 1394 periods walked per system.
    pub periods: u64,
}

impl Default for Table4Options {
    fn default() -> Self {
        Table4Options {
            config: MahruConfig::seed002(),
            cycles: 500,
            error_probability: 0.0,
            reads: 100_000,
            periods: 1000,
        }
    }
}

/// The CAN cycle's figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CanCycle {
    /// Frames the computer sends per cycle (SYNC and set-points).
    pub frames_sent: usize,
    /// Frames the modules send per cycle.
    pub frames_received: usize,
    /// Send time, us.
    pub send: Stat,
    /// Receive time, us.
    pub receive: Stat,
    /// The whole cycle, us.
    pub total: Stat,
    /// The whole cycle if every frame had its worst-case stuffing, us.
    pub worst_case_us: f64,
    /// Mean stuff bits per 8-byte frame.
    pub stuff_bits_per_frame: f64,
    /// Error frames met.
    pub error_frames: usize,
    /// Frames that never got through (bus-off).
    pub lost_frames: usize,
}

/// The 1394 figures of one system.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Ieee1394Cycle {
    /// The system.
    pub rtos: &'static str,
    /// A 4-byte read: call to the request's ack, us.
    pub request: Stat,
    /// A 4-byte read: the ack to the return, us.
    pub response: Stat,
    /// A 4-byte read: call to return, us.
    pub read: Stat,
    /// The 14-module cycle's I/O (all reads and the QWRITE), us.
    pub cycle_io: Stat,
    /// The same cycle's time on the wire alone, us.
    pub cycle_wire_us: f64,
    /// The seed's row: request, response, total, us.
    pub paper: [f64; 3],
}

/// Ratios CAN : 1394.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Ratios {
    /// The system.
    pub rtos: &'static str,
    /// The seed's: its CAN total over its 1394 read.
    pub paper: f64,
    /// The same quotient from the models: CAN cycle (median) over the
    /// simulated 4-byte read's worst case.
    pub model_as_the_seed: f64,
    /// Cycle against cycle, with the computer's software (medians).
    pub cycle_to_cycle: f64,
    /// Cycle against cycle on the wire alone.
    pub wire_to_wire: f64,
}

/// Table IV.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Table4Report {
    /// CAN.
    pub can: CanCycle,
    /// The seed's CAN row.
    pub paper_can: [f64; 3],
    /// 1394, per system.
    pub ieee1394: Vec<Ieee1394Cycle>,
    /// The ratios, per system.
    pub ratios: Vec<Ratios>,
    /// S400 over 1 Mb/s.
    pub bit_rate_ratio: f64,
}

fn can_err(e: firelink_can::CanError) -> TestbedError {
    TestbedError::Config(format!("CAN model: {e}"))
}

fn id(raw: u16) -> Result<CanId, TestbedError> {
    CanId::new(raw).map_err(can_err)
}

/// Frames of `bytes` cut into 8-byte pieces with identifiers from `base`.
fn frames(base: u16, bytes: &[u8]) -> Result<Vec<Frame>, TestbedError> {
    bytes
        .chunks(8)
        .enumerate()
        .map(|(k, chunk)| Frame::data(id(base + k as u16)?, chunk).map_err(can_err))
        .collect()
}

fn us(d: Duration) -> f32 {
    (d.as_secs_f64() * 1e6) as f32
}

/// A bus duration (picoseconds) as a `Duration`.
fn duration(d: firelink_bus::SimDuration) -> Duration {
    Duration::from_nanos(d.0 / 1000)
}

/// Run the CAN cycles.
fn can_cycles(options: &Table4Options) -> Result<CanCycle, TestbedError> {
    let config = &options.config;
    let layout = config.layout()?;
    let gait = Gait::new(config);
    let timing = config.responder_timing();
    let mut bus = CanBus::new(CanConfig {
        error_probability: options.error_probability,
        seed: config.seed,
        ..CanConfig::default()
    })
    .map_err(can_err)?;
    let host = bus.add_node("sbc");
    let nodes: Vec<usize> = layout
        .modules
        .iter()
        .map(|m| bus.add_node(m.name.clone()))
        .collect();
    let period = config.period().as_secs_f64();
    let (mut send, mut receive, mut total) = (vec![], vec![], vec![]);
    let (mut stuff, mut frames_8) = (0usize, 0usize);
    let (mut sent, mut received, mut worst_bits, mut lost) = (0, 0, 0, 0);
    let bit = |bits: usize| bus.bit_time() * bits as u32;
    let bit_us = us(bit(1));
    for cycle in 0..options.cycles.max(1) {
        let t = 2.0 + f64::from(cycle) * period;
        // One cycle per period (or at once, if the last one ran over).
        let start = Duration::from_secs_f64(f64::from(cycle) * period).max(bus.now());
        // Receive: SYNC, then every module's block.
        let sync = Frame::data(id(0x080)?, &[]).map_err(can_err)?;
        bus.submit(host, sync, start).map_err(can_err)?;
        let sync_done = bus
            .step()
            .ok_or_else(|| can_err(firelink_can::CanError::NoSuchNode(host)))?;
        let mut expected = 0;
        let mut cycle_worst = sync.bits().max(worst_case_bits(0));
        let mut sensors = 0u16;
        for (i, spec) in layout.modules.iter().enumerate() {
            let (base, bytes) = match spec.kind {
                ModuleKind::ForceTorque => {
                    let k = sensors;
                    sensors += 1;
                    let load = (400.0 + 100.0 * (t * 5.0 + f64::from(k)).sin()) * 1e3;
                    let block = FtBlock {
                        force_mn: [(load * 0.1) as i32, -(load * 0.02) as i32, load as i32],
                        torque_mnm: [(load * 0.01) as i32, -(load * 0.03) as i32, 150],
                    };
                    let mut b = [0u8; FtBlock::LEN];
                    block.emit(&mut b).map_err(firelink_host::HostError::Wire)?;
                    (0x380 + 3 * k, b.to_vec())
                }
                _ => {
                    let s = gait.setpoint(spec.mod_id, t);
                    let block = JointBlock {
                        mod_id: spec.mod_id,
                        state: ModuleState::Running,
                        sequence: cycle as u16,
                        position_urad: (s.position * 1e6) as i32,
                        velocity_urad_s: (s.velocity * 1e6) as i32,
                        current_ma: (s.acceleration * 50.0) as i32,
                        target_urad: (s.position * 1e6) as i32 + 800,
                        torque_mnm: (s.acceleration * 900.0) as i32,
                        servo_ticks: 5000 + 10 * cycle,
                        flags: JointBlock::AMPLIFIER_ON | JointBlock::PARAMETERS_VALID,
                    };
                    let mut b = [0u8; JointBlock::LEN];
                    block.emit(&mut b).map_err(firelink_host::HostError::Wire)?;
                    (0x300 + 4 * u16::from(spec.mod_id.0), b.to_vec())
                }
            };
            let first = sync_done.delivered_at + duration(timing.poll) / 2 + duration(timing.fixed);
            for (k, f) in frames(base, &bytes)?.into_iter().enumerate() {
                let ready = first + duration(timing.per_byte) * (8 * (k + 1)) as u32;
                bus.submit(nodes[i], f, ready).map_err(can_err)?;
                expected += 1;
                cycle_worst += worst_case_bits(f.payload().len());
            }
        }
        let mut last: Option<Delivery> = None;
        for _ in 0..expected {
            let Some(d) = bus.step() else { break };
            if d.outcome == Outcome::BusOff {
                lost += 1;
            }
            stuff += d.frame.stuff_bits();
            frames_8 += usize::from(d.frame.payload().len() == 8);
            last = Some(d);
        }
        received = expected;
        let recv_end = last.map_or(sync_done.delivered_at, |d| d.delivered_at);
        // Send: the set-points.
        let send_start = bus.now();
        let mut slots = [0u8; 320];
        for (k, chunk) in slots.chunks_exact_mut(SetpointSlot::LEN).enumerate() {
            let s = gait.setpoint(ModId(k as u8), t);
            let slot = SetpointSlot {
                mod_id: k as u8,
                valid: true,
                sequence: cycle as u16,
                position_urad: (s.position * 1e6) as i32,
                velocity_urad_s: (s.velocity * 1e6) as i32,
                acceleration_mrad_s2: (s.acceleration * 1e3) as i32,
                torque_mnm: (s.acceleration * 900.0) as i32,
            };
            slot.emit(chunk).map_err(firelink_host::HostError::Wire)?;
        }
        let setpoint_frames = frames(0x200, &slots)?;
        sent = setpoint_frames.len() + 1;
        for f in &setpoint_frames {
            bus.submit(host, *f, send_start).map_err(can_err)?;
            cycle_worst += worst_case_bits(8);
        }
        let mut send_end = send_start;
        for d in bus.run_until_idle() {
            stuff += d.frame.stuff_bits();
            frames_8 += usize::from(d.frame.payload().len() == 8);
            send_end = d.delivered_at;
        }
        let sync_time = sync_done.delivered_at.saturating_sub(start);
        let send_time = sync_time + send_end.saturating_sub(send_start);
        let recv_time = recv_end.saturating_sub(sync_done.delivered_at);
        send.push(us(send_time));
        receive.push(us(recv_time));
        total.push(us(send_time + recv_time));
        worst_bits = cycle_worst;
    }
    Ok(CanCycle {
        frames_sent: sent,
        frames_received: received,
        send: Stat::of(&mut send),
        receive: Stat::of(&mut receive),
        total: Stat::of(&mut total),
        worst_case_us: (worst_bits as f64 * f64::from(bit_us) * 10.0).round() / 10.0,
        stuff_bits_per_frame: ((stuff as f64 / (frames_8.max(1)) as f64) * 100.0).round() / 100.0,
        error_frames: bus.errors().len(),
        lost_frames: lost,
    })
}

/// The 14-module 1394 cycle's time on the wire alone: every read
/// (request, ack, response, ack at S400 over the module's hops) and the
/// QWRITE broadcast.
fn wire_cycle_us(config: &MahruConfig) -> Result<f64, TestbedError> {
    let b = build_bus(&config.module_configs(), config.seed)?;
    let timing: &BusTiming = b.bus.timing();
    let layout = config.layout()?;
    let mut total = Duration::ZERO;
    for (spec, placed) in layout.modules.iter().zip(&b.modules) {
        let payload = match spec.kind {
            ModuleKind::ForceTorque => FtBlock::LEN,
            _ => JointBlock::LEN,
        };
        let t = timing.nominal_block_read(payload, Speed::S400, placed.hops);
        total += duration(t);
    }
    // QWRITE: a 16-byte header, its CRC, 320 bytes and the data CRC.
    let speed = config.broadcast_speed()?;
    total += duration(timing.packet_time(16 + 4 + 320 + 4, speed));
    Ok((total.as_secs_f64() * 1e7).round() / 10.0)
}

/// Run Table IV.
///
/// # Errors
/// A configuration that cannot be built or run; cycles beyond
/// [`MAX_CAN_CYCLES`], periods beyond [`MAX_PERIODS`], an error
/// probability outside 0..=1.
pub fn run_table4(
    options: &Table4Options,
    mut progress: impl FnMut(&str),
) -> Result<Table4Report, TestbedError> {
    let config = &options.config;
    config.validate()?;
    if options.cycles > MAX_CAN_CYCLES || options.periods > MAX_PERIODS {
        return Err(TestbedError::Config(format!(
            "Table IV: {} CAN cycles and {} periods: at most {MAX_CAN_CYCLES} and {MAX_PERIODS}",
            options.cycles, options.periods
        )));
    }
    if !(0.0..=1.0).contains(&options.error_probability) {
        return Err(TestbedError::Config(format!(
            "Table IV: error probability {} is out of range: 0 to 1",
            firelink_wire::human::Number(options.error_probability)
        )));
    }
    progress("CAN: the 14-module cycle at 1 Mb/s");
    let can = can_cycles(options)?;
    let wire = wire_cycle_us(config)?;
    let mut ieee1394 = Vec::new();
    let mut ratios = Vec::new();
    for (rtos, paper) in PAPER_1394 {
        progress(&format!("1394 under {rtos}: 4-byte reads and the cycle"));
        let t3 = run_table3(
            &Table3Options {
                reads: options.reads,
                payloads: vec![4],
                rtos: vec![rtos],
                responder: config.responder_timing(),
                seed: config.seed,
                threads: 1,
            },
            |_| {},
        )?;
        let read = t3
            .point(rtos, 4)
            .cloned()
            .ok_or_else(|| TestbedError::Config("Table IV: no 4-byte point".into()))?;
        let cfg = MahruConfig {
            rtos: rtos.name().into(),
            ..config.clone()
        };
        let mut r = bring_up(&cfg)?;
        let mut main = MainLoop::new(&cfg, cfg.period());
        let mut phases = PhaseSamples::default();
        let mut io = Vec::new();
        for _ in 0..options.periods.max(1) {
            let p = main
                .period_once(&mut r.controller, |_| {})
                .map_err(motion)?;
            phases.push(&p);
            io.push((p.read_us + p.write_us) as f32);
        }
        let _ = r.controller.stop();
        let cycle_io = Stat::of(&mut io);
        ratios.push(Ratios {
            rtos: rtos.name(),
            paper: (PAPER_CAN[2] / paper[2] * 10.0).round() / 10.0,
            model_as_the_seed: (can.total.p50 / read.total.max * 10.0).round() / 10.0,
            cycle_to_cycle: (can.total.p50 / cycle_io.p50 * 10.0).round() / 10.0,
            wire_to_wire: (can.total.p50 / wire * 10.0).round() / 10.0,
        });
        ieee1394.push(Ieee1394Cycle {
            rtos: rtos.name(),
            request: read.request,
            response: read.response,
            read: read.total,
            cycle_io,
            cycle_wire_us: wire,
            paper,
        });
    }
    Ok(Table4Report {
        can,
        paper_can: PAPER_CAN,
        ieee1394,
        ratios,
        bit_rate_ratio: (Speed::S400.bits_per_second() as f64 / 1e6 * 10.0).round() / 10.0,
    })
}

impl fmt::Display for Table4Report {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let c = &self.can;
        writeln!(
            f,
            "Table IV: CAN 2.0A at 1 Mb/s against IEEE 1394 (us; model figures are medians, p99 and max in brackets)"
        )?;
        writeln!(
            f,
            "{:34} {:>18} {:>18} {:>18}",
            "", "send / request", "recv / response", "total"
        )?;
        writeln!(
            f,
            "{:34} {:>18.0} {:>18.0} {:>18.0}",
            "CAN, the seed ([16], 8-byte frames)",
            self.paper_can[0],
            self.paper_can[1],
            self.paper_can[2]
        )?;
        let s = |x: &Stat| format!("{:.0} [{:.0}]", x.p50, x.max);
        writeln!(
            f,
            "{:34} {:>18} {:>18} {:>18}",
            format!("CAN model, this robot's cycle"),
            s(&c.send),
            s(&c.receive),
            s(&c.total)
        )?;
        for i in &self.ieee1394 {
            writeln!(
                f,
                "{:34} {:>18.0} {:>18.0} {:>18.0}",
                format!("1394 {}, the seed (4-byte read)", i.rtos),
                i.paper[0],
                i.paper[1],
                i.paper[2]
            )?;
            let w = |x: &Stat| format!("{:.1} [{:.1}]", x.p50, x.max);
            writeln!(
                f,
                "{:34} {:>18} {:>18} {:>18}",
                format!("1394 {}, simulated 4-byte read", i.rtos),
                w(&i.request),
                w(&i.response),
                w(&i.read)
            )?;
            writeln!(
                f,
                "{:34} {:>18} {:>18} {:>18}",
                format!("1394 {}, simulated cycle I/O", i.rtos),
                "",
                "",
                w(&i.cycle_io)
            )?;
        }
        writeln!(
            f,
            "CAN cycle: {} frames sent, {} received, {:.2} stuff bits per 8-byte frame, worst-case stuffing {:.0} us, {} error frames, {} lost",
            c.frames_sent,
            c.frames_received,
            c.stuff_bits_per_frame,
            c.worst_case_us,
            c.error_frames,
            c.lost_frames
        )?;
        if let Some(i) = self.ieee1394.first() {
            writeln!(
                f,
                "1394 cycle on the wire alone (14 reads at S400 and the QWRITE): {:.1} us; bit rates S400 : 1 Mb/s = {:.0}",
                i.cycle_wire_us, self.bit_rate_ratio
            )?;
        }
        writeln!(
            f,
            "ratios CAN : 1394      the seed   models as the seed   cycle : cycle   wire : wire"
        )?;
        for r in &self.ratios {
            writeln!(
                f,
                "  {:8}          {:8.1}x   {:18.1}x   {:12.1}x   {:10.1}x",
                r.rtos, r.paper, r.model_as_the_seed, r.cycle_to_cycle, r.wire_to_wire
            )?;
        }
        Ok(())
    }
}
