//! The host's own CPU per servo cycle: one 28-axis dVRK cycle (seed 000's
//! robot on 8 QLA1 Rev 8 boards, broadcast protocol) with the I/O
//! replaced by a recorded hub block, so that only what the host program
//! computes is timed: the hub block checked and parsed into 8 read blocks
//! and latched, the runner's check and compute for 28 axes (encoders,
//! pots, velocity, trajectory, PID, safety monitor, DAC codes) and the
//! command block built.
//!
//! [`RecordedCycle::record`] runs the demo's program on emulated boards on
//! the simulated bus (configure, power on, home, activate, the demo's
//! motions) for a while, then freezes the port ([`HubReplay`]): from then
//! on every query is answered by the last hub block the boards sent (its
//! headers carrying the new query's sequence, so every check passes), the
//! port's clock advances one period per query and nothing is sent
//! anywhere. Frozen inputs with the demo's moves would soon be a following
//! error, so the joints then follow the same kinds of motion with tiny
//! amplitudes: the same sinusoids and point-to-point moves to sample, PIDs
//! and safety checks to run, and no fault.
//!
//! Used by the criterion benchmark (`cargo bench -p firelink-testbed
//! --bench host_cycle`) and by `firelink bench`
//! ([`measure_with_floor`](RecordedCycle::measure_with_floor): the
//! cycle beside its floor, the bare loop, in one run).

use std::hint::black_box;
use std::time::{Duration, Instant};

use firelink_board::qla::config::Profile;
use firelink_control::config::{IoConfig, presets};
use firelink_control::runner::{Pacing, Percentiles, Robot, RobotSettings};
use firelink_control::trajectory::{Motion, PointToPoint, Sinusoid};
use firelink_host::WatchdogSetting;
use firelink_host::error::{HostError, Result};
use firelink_host::link_stats::LinkStats;
use firelink_host::port::{Dest, LinkFilter, Port};
use firelink_host::qla::io::{IoOptions, IoSystem};
use firelink_host::qla::scan::Protocol;
use firelink_host::sim::SimPort;
use firelink_wire::qla::address::{COMMAND_BLOCK_OFFSET, HUB_MEMORY_OFFSET, HUB_QUERY_OFFSET};
use firelink_wire::qla::broadcast::{HubHeader, Query};
use firelink_wire::qla::realtime::BlockFormat;

use crate::TestbedError;
use crate::demo::motion_for;
use crate::rig;

/// A port that forwards every call to `inner` and keeps the last hub block
/// read, until [`freeze`](HubReplay::freeze): from then on it answers the
/// broadcast protocol's cycle itself from that block.
pub struct HubReplay<P: Port> {
    inner: P,
    hub: Vec<u8>,
    frozen: Option<Frozen>,
    /// Once [`digest_writes`](HubReplay::digest_writes) was called: the
    /// FNV-1a digest of every block written while frozen (the command
    /// blocks, in order).
    written: Option<u64>,
}

/// FNV-1a 64's offset basis.
pub const FNV_OFFSET: u64 = 0xCBF2_9CE4_8422_2325;

/// `bytes` folded into the FNV-1a 64 digest `digest` (start from
/// [`FNV_OFFSET`]).
pub fn fnv1a(digest: u64, bytes: &[u8]) -> u64 {
    bytes.iter().fold(digest, |d, &b| {
        (d ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01B3)
    })
}

/// The replay's state once frozen.
struct Frozen {
    /// Where each board's entry header is in the hub block, its format and
    /// the header as recorded (made valid).
    entries: Vec<(usize, BlockFormat, u32)>,
    /// The sequence of the last query.
    seq: u16,
    /// The port's clock, advanced one period per query.
    now: Duration,
    period: Duration,
}

impl<P: Port> HubReplay<P> {
    /// Forward to `port`, recording hub reads.
    pub fn new(port: P) -> HubReplay<P> {
        HubReplay {
            inner: port,
            hub: Vec::new(),
            frozen: None,
            written: None,
        }
    }

    /// From now on fold every block written while frozen into a digest
    /// ([`written_digest`](Self::written_digest)): the replayed cycles'
    /// command blocks, to compare two builds' outputs.
    pub fn digest_writes(&mut self) {
        self.written.get_or_insert(FNV_OFFSET);
    }

    /// The digest of the blocks written since
    /// [`digest_writes`](Self::digest_writes), if it was called.
    pub fn written_digest(&self) -> Option<u64> {
        self.written
    }

    /// A block written while frozen: into the digest, if one is kept.
    fn frozen_block(&mut self, data: &[u8]) {
        if let Some(d) = self.written.as_mut() {
            *d = fnv1a(*d, data);
        }
        black_box(data);
    }

    /// From now on answer from the last hub block read: `entries` are the
    /// byte offsets of the boards' entries in it and their formats; every
    /// query moves the clock on by `period`.
    ///
    /// # Errors
    /// [`TestbedError::Config`] when no hub block was read yet or an entry
    /// lies outside it.
    pub fn freeze(
        &mut self,
        entries: Vec<(usize, BlockFormat)>,
        period: Duration,
    ) -> core::result::Result<(), TestbedError> {
        if self.hub.is_empty() || entries.iter().any(|&(at, _)| at + 4 > self.hub.len()) {
            return Err(TestbedError::Config(
                "hub replay: no hub block recorded to replay".into(),
            ));
        }
        self.rewrite_headers(&entries, 1);
        let entries = entries
            .into_iter()
            .filter_map(|(at, format)| {
                let q = self.hub.get(at..at + 4)?;
                Some((at, format, u32::from_be_bytes([q[0], q[1], q[2], q[3]])))
            })
            .collect();
        self.frozen = Some(Frozen {
            entries,
            seq: 1,
            now: self.inner.now(),
            period,
        });
        Ok(())
    }

    /// The recorded hub block.
    pub fn hub(&self) -> &[u8] {
        &self.hub
    }

    /// A new query: the clock moves on a period and the hub answers `seq`.
    fn answer(&mut self, seq: u16) {
        if let Some(f) = self.frozen.as_mut() {
            f.now += f.period;
            f.seq = seq;
        }
    }

    /// The recorded hub block into `out`, each entry's header answering the
    /// last query (its sequence bits replaced; whole quadlets written, as a
    /// port's receive writes them).
    fn replay_hub(&self, out: &mut [u8]) -> bool {
        let (Some(f), Some(hub)) = (&self.frozen, self.hub.get(..out.len())) else {
            return false;
        };
        if hub.len() != self.hub.len() {
            return false;
        }
        out.copy_from_slice(hub);
        let seq = u32::from(f.seq);
        for &(at, format, header) in &f.entries {
            let word = match format {
                // seq_low:8 in bits 23:16.
                BlockFormat::Rev8 => (header & !0x00FF_0000) | (seq & 0xFF) << 16,
                // seq:16 in bits 31:16.
                BlockFormat::Rev4 | BlockFormat::Rev7 => (header & 0xFFFF) | seq << 16,
            };
            if let Some(q) = out.get_mut(at..at + 4) {
                q.copy_from_slice(&word.to_be_bytes());
            }
        }
        true
    }

    /// Each entry's header rewritten as a board that heard `seq` writes it.
    fn rewrite_headers(&mut self, entries: &[(usize, BlockFormat)], seq: u16) {
        for &(at, format) in entries {
            let Some(q) = self.hub.get_mut(at..at + 4) else {
                continue;
            };
            let word = u32::from_be_bytes([q[0], q[1], q[2], q[3]]);
            let header = match HubHeader::from_word(word, format) {
                HubHeader::Rev7 { time, .. } => HubHeader::Rev7 { seq, time },
                HubHeader::Rev8 {
                    quadlets,
                    update_time,
                    ..
                } => HubHeader::Rev8 {
                    quadlets,
                    seq_low: seq as u8,
                    seq_error: false,
                    update_time,
                },
            };
            if let Ok(w) = header.to_word() {
                q.copy_from_slice(&w.to_be_bytes());
            }
        }
    }

    fn frozen_write(&mut self, offset: u64, value: u32) {
        if offset == HUB_QUERY_OFFSET
            && let Ok(q) = Query::parse(value)
        {
            self.answer(q.seq);
        }
    }
}

/// What a frozen port cannot answer.
fn not_recorded(offset: u64) -> HostError {
    HostError::InvalidRequest {
        what: "hub replay: only the hub block is recorded",
        value: offset as u32,
    }
}

impl<P: Port> Port for HubReplay<P> {
    fn name(&self) -> &str {
        "hub-replay"
    }

    fn read_quadlet(&mut self, dest: Dest, offset: u64) -> Result<u32> {
        if self.frozen.is_some() {
            return Err(not_recorded(offset));
        }
        self.inner.read_quadlet(dest, offset)
    }

    fn write_quadlet(&mut self, dest: Dest, offset: u64, value: u32) -> Result<()> {
        if self.frozen.is_some() {
            self.frozen_write(offset, value);
            return Ok(());
        }
        self.inner.write_quadlet(dest, offset, value)
    }

    fn read_block(&mut self, dest: Dest, offset: u64, out: &mut [u8]) -> Result<()> {
        if self.frozen.is_some() {
            return if offset == HUB_MEMORY_OFFSET && self.replay_hub(out) {
                Ok(())
            } else {
                Err(not_recorded(offset))
            };
        }
        self.inner.read_block(dest, offset, out)?;
        if offset == HUB_MEMORY_OFFSET {
            self.hub.clear();
            self.hub.extend_from_slice(out);
        }
        Ok(())
    }

    fn write_block(&mut self, dest: Dest, offset: u64, data: &[u8]) -> Result<()> {
        if self.frozen.is_some() {
            self.frozen_block(data);
            return Ok(());
        }
        self.inner.write_block(dest, offset, data)
    }

    fn start_write_quadlet(&mut self, dest: Dest, offset: u64, value: u32) -> Result<()> {
        if self.frozen.is_some() {
            self.frozen_write(offset, value);
            return Ok(());
        }
        self.inner.start_write_quadlet(dest, offset, value)
    }

    fn start_write_block(&mut self, dest: Dest, offset: u64, data: &[u8]) -> Result<()> {
        if self.frozen.is_some() {
            self.frozen_block(data);
            return Ok(());
        }
        self.inner.start_write_block(dest, offset, data)
    }

    fn wait(&mut self, duration: Duration) {
        if self.frozen.is_none() {
            self.inner.wait(duration);
        }
    }

    fn begin_cycle(&mut self) {
        self.inner.begin_cycle();
    }

    fn end_cycle(&mut self) {
        self.inner.end_cycle();
    }

    fn now(&self) -> Duration {
        match &self.frozen {
            Some(f) => f.now,
            None => self.inner.now(),
        }
    }

    fn generation(&self) -> u32 {
        self.inner.generation()
    }

    fn acknowledges_writes(&self) -> bool {
        self.frozen.is_some() || self.inner.acknowledges_writes()
    }

    fn link_stats(&self) -> LinkStats {
        self.inner.link_stats()
    }

    fn candidate_nodes(&self) -> core::ops::Range<u8> {
        self.inner.candidate_nodes()
    }

    fn add_link_filter(&mut self, filter: Box<dyn LinkFilter>) -> Result<()> {
        self.inner.add_link_filter(filter)
    }

    fn takes_link_filters(&self) -> bool {
        self.inner.takes_link_filters()
    }
}

/// The robot of a [`RecordedCycle`].
pub type ReplayedRobot = Robot<IoSystem<HubReplay<SimPort>>>;

/// Cycles of the demo's motion on the simulated bus before the hub block
/// is recorded (0.1 s at 6 kHz).
const LIVE_CYCLES: u64 = 600;

/// Replayed cycles run before the first one is handed out (PIDs and
/// velocity estimates settle on the frozen inputs; none may fault).
const SETTLE_CYCLES: u64 = 200;

/// Seed 000's 28-axis dVRK cycle with the I/O replaced by a recorded hub
/// block (see the module docs).
pub struct RecordedCycle {
    robot: ReplayedRobot,
    /// The bare loop's buffers ([`bare_cycle`](Self::bare_cycle)): the
    /// hub read's and the command block's, of the host's sizes.
    bare_hub: Vec<u8>,
    bare_commands: Vec<u8>,
    /// The bare loop's query sequence.
    bare_seq: u16,
}

/// Per-cycle times of the replayed host cycle and of its floor, the bare
/// loop, measured in alternating blocks in one run
/// ([`RecordedCycle::measure_with_floor`]), us.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CycleAndFloor {
    /// The replayed host cycles.
    pub cycle: Percentiles,
    /// The bare loop's cycles.
    pub floor: Percentiles,
}

/// Cycles per block of [`RecordedCycle::measure_with_floor`]: the host
/// cycle's blocks and the bare loop's alternate.
pub const FLOOR_BLOCK_CYCLES: usize = 500;

/// The same kind of motion as the demo's for joint `i` (see
/// [`motion_for`]), with amplitudes a thousandth of the demo's: frozen
/// inputs follow it without a following error.
fn tiny_motion(config: &IoConfig, i: usize, here: f64) -> Motion {
    match motion_for(config, i, here) {
        Motion::Sinusoid(_) => {
            let f = 0.4 + 0.1 * (i % 4) as f64;
            Sinusoid::new(1e-5, f, 0.0, here, 0.5).map_or(Motion::Hold(here), Motion::Sinusoid)
        }
        Motion::PointToPoint(_) => PointToPoint::new(here, here + 1e-5, 0.1, 0.5)
            .map_or(Motion::Hold(here), Motion::PointToPoint),
        other => other,
    }
}

impl RecordedCycle {
    /// Run the demo's program on seed 000's dVRK on the simulated bus,
    /// record a hub block mid-motion and freeze the port on it.
    ///
    /// # Errors
    /// The rig, the scan or the program failed, or a replayed cycle
    /// faulted.
    pub fn record() -> core::result::Result<RecordedCycle, TestbedError> {
        let config = presets::dvrk_seed000();
        let boards = rig::board_configs(&config, Profile::Rev8, config.board_slots());
        let (port, _) = rig::sim_port(boards, false)?;
        let (io, _) = IoSystem::open(
            HubReplay::new(port),
            IoOptions {
                protocol: Some(Protocol::Broadcast),
                ..IoOptions::default()
            },
        )?;
        if io.protocol() != Protocol::Broadcast {
            return Err(TestbedError::Config(
                "recorded cycle: the boards do not support the broadcast protocol".into(),
            ));
        }
        let settings = RobotSettings {
            period: crate::demo::servo_period(6000.0)?,
            watchdog: WatchdogSetting::default(),
            // The timing record is not what is measured here.
            max_samples: 1 << 16,
            ..RobotSettings::default()
        };
        let mut robot = Robot::new(io, &config, settings)?;
        robot.configure()?;
        robot.power_on()?;
        robot.home()?;
        robot.activate()?;
        for i in 0..robot.joint_count() {
            let here = robot.position(i).unwrap_or(0.0);
            robot.set_motion(i, motion_for(&config, i, here))?;
        }
        robot.run(LIVE_CYCLES, Pacing::Virtual, 0, |_| {})?;
        // Each board's hub entry: its header, then its block.
        let mut entries = Vec::new();
        let mut at = 0;
        for b in robot.io().boards() {
            let layout = b.info().layout;
            entries.push((at, layout.format()));
            at += layout.broadcast_quadlets() * 4;
        }
        let period = Duration::from_secs_f64(robot.period());
        robot.io_mut().port_mut().freeze(entries, period)?;
        for i in 0..robot.joint_count() {
            let here = robot.position(i).unwrap_or(0.0);
            robot.set_motion(i, tiny_motion(&config, i, here))?;
        }
        let hub_len = robot.io().port().hub().len();
        let command_len = robot
            .io()
            .boards()
            .iter()
            .map(|b| b.info().layout.write_block_len())
            .sum();
        let mut recorded = RecordedCycle {
            robot,
            bare_hub: vec![0; hub_len],
            bare_commands: vec![0; command_len],
            bare_seq: 0,
        };
        for _ in 0..SETTLE_CYCLES {
            recorded.cycle().map_err(TestbedError::Config)?;
        }
        Ok(recorded)
    }

    /// One host cycle: parse the replayed hub block, check, compute 28
    /// axes, build the command block.
    ///
    /// # Errors
    /// A fault, or a board that missed the cycle (neither happens with the
    /// recorded block).
    #[inline(never)]
    pub fn cycle(&mut self) -> core::result::Result<(), String> {
        self.robot.cycle().map_err(|f| f.to_string())?;
        match self.robot.last_report() {
            Some(r) if r.all_ok() => Ok(()),
            r => Err(format!("replayed cycle not clean: {r:?}")),
        }
    }

    /// The bare loop: one cycle of the frozen port's own part and nothing
    /// else, the floor of [`cycle`](Self::cycle): the query written, the
    /// recorded hub block replayed into a buffer of the host's hub read
    /// and a command block of the host's size handed to the port, with no
    /// parse, no control and no command built.
    ///
    /// # Errors
    /// The port refused a call (it does not, frozen).
    #[inline(never)]
    pub fn bare_cycle(&mut self) -> core::result::Result<(), String> {
        self.bare_seq = self.bare_seq.wrapping_add(1).max(1);
        let query = Query {
            seq: self.bare_seq,
            board_mask: 0xFF,
        }
        .to_word()
        .map_err(|e| e.to_string())?;
        let port = self.robot.io_mut().port_mut();
        port.begin_cycle();
        port.start_write_quadlet(Dest::BROADCAST, HUB_QUERY_OFFSET, query)
            .and_then(|()| port.read_block(Dest::node(0), HUB_MEMORY_OFFSET, &mut self.bare_hub))
            .and_then(|()| {
                port.start_write_block(Dest::BROADCAST, COMMAND_BLOCK_OFFSET, &self.bare_commands)
            })
            .map_err(|e| e.to_string())?;
        port.end_cycle();
        black_box(&self.bare_hub);
        Ok(())
    }

    /// `digest` with the robot's state after the last cycle folded in
    /// ([`fnv1a`] over the bits of every joint's position, velocity,
    /// setpoint, commanded current and pot position, then the lifecycle
    /// state): two builds that compute the same give the same digest.
    pub fn fold_state(&self, digest: u64) -> u64 {
        let r = &self.robot;
        let d = (0..r.joint_count()).fold(digest, |d, i| {
            [
                r.position(i),
                r.velocity(i),
                r.setpoint(i),
                r.commanded_current(i),
                r.potentiometer(i),
            ]
            .into_iter()
            .fold(d, |d, v| {
                fnv1a(d, &v.map_or(u64::MAX, f64::to_bits).to_le_bytes())
            })
        });
        fnv1a(d, format!("{:?}", r.state()).as_bytes())
    }

    /// The robot.
    pub fn robot(&self) -> &ReplayedRobot {
        &self.robot
    }

    /// The robot, mutable (to run parts of the cycle alone).
    pub fn robot_mut(&mut self) -> &mut ReplayedRobot {
        &mut self.robot
    }

    /// Time `cycles` replayed cycles and as many cycles of the bare loop
    /// ([`bare_cycle`](Self::bare_cycle)), one by one on the machine's
    /// monotonic clock, in alternating blocks of [`FLOOR_BLOCK_CYCLES`]
    /// after `warm_up` untimed cycles of each: the two sets of
    /// percentiles are from the same minutes of the same run, so their
    /// ratio does not move with the machine's speed as much as either.
    ///
    /// # Errors
    /// A replayed cycle failed.
    pub fn measure_with_floor(
        &mut self,
        warm_up: u64,
        cycles: usize,
    ) -> core::result::Result<CycleAndFloor, TestbedError> {
        for _ in 0..warm_up {
            self.cycle().map_err(TestbedError::Config)?;
            self.bare_cycle().map_err(TestbedError::Config)?;
        }
        let mut host = vec![0f32; cycles];
        let mut bare = vec![0f32; cycles];
        for (host, bare) in host
            .chunks_mut(FLOOR_BLOCK_CYCLES)
            .zip(bare.chunks_mut(FLOOR_BLOCK_CYCLES))
        {
            for slot in host.iter_mut() {
                *slot = timed_us(|| self.cycle())?;
            }
            for slot in bare.iter_mut() {
                *slot = timed_us(|| self.bare_cycle())?;
            }
        }
        Ok(CycleAndFloor {
            cycle: Percentiles::of(&mut host),
            floor: Percentiles::of(&mut bare),
        })
    }
}

/// `run` timed on the monotonic clock, us.
fn timed_us(
    run: impl FnOnce() -> core::result::Result<(), String>,
) -> core::result::Result<f32, TestbedError> {
    let start = Instant::now();
    let r = run();
    let spent = start.elapsed();
    r.map_err(TestbedError::Config)?;
    Ok((spent.as_secs_f64() * 1e6) as f32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use firelink_control::lifecycle::State;
    use firelink_wire::qla::realtime::{ReadBlock, ReadBlockRepr};

    /// The replayed cycles run the whole program on the recorded inputs:
    /// every board latches its recorded block, the robot stays Active with
    /// no fault, every joint is where the recording left it and gets a
    /// current command.
    #[test]
    fn replayed_cycles_latch_the_recorded_blocks() {
        let mut r = RecordedCycle::record().unwrap();
        let positions: Vec<f64> = (0..28).map(|i| r.robot().position(i).unwrap()).collect();
        for _ in 0..300 {
            r.cycle().unwrap();
        }
        let robot = r.robot();
        assert_eq!(robot.state(), State::Active);
        assert!(robot.fault().is_none());
        assert_eq!(robot.joint_count(), 28);
        assert_eq!(robot.io().boards().len(), 8);
        for (i, p) in positions.iter().enumerate() {
            assert_eq!(robot.position(i), Some(*p), "joint {i}");
            assert!(robot.commanded_current(i).unwrap().is_finite());
        }
        assert!((0..28).any(|i| robot.commanded_current(i) != Some(0.0)));
        let hub = robot.io().port().hub();
        let mut at = 4;
        for b in robot.io().boards() {
            let layout = b.info().layout;
            let len = layout.read_block_len();
            let block = ReadBlock::new_checked(&hub[at..at + len], layout).unwrap();
            assert!(b.is_valid());
            assert_eq!(b.input(), &ReadBlockRepr::parse(&block).unwrap());
            at += layout.broadcast_quadlets() * 4;
        }
        assert_eq!(robot.io().stats().total_errors(), 0);
    }
}
