//! A port-level stand-in for emulated boards, for tests and for running the
//! runner before (or without) the full bus emulation.
//!
//! [`LoopbackPort`] implements [`Port`] directly: no bus, no packets, only
//! the register and block semantics of QLA1 boards at firmware Rev 8 that
//! the host library uses (identity registers, real-time block read and
//! write, broadcast query / hub read / command broadcast, the watchdog,
//! motor power and amplifier enables), each joint driven by a second-order
//! plant whose natural frequency matches the configured PID gains. Virtual
//! time advances by a fixed cost per transaction (seed 000's PC: 32 us per
//! read, 34 us per write, 2.51 us per broadcast write) and by
//! [`Port::wait`].
//!
//! Faults can be injected: a corrupt query (every board answers with the
//! wrong sequence), a lost board (its node stops answering) and a stopped
//! host is simply not calling the port while virtual time passes
//! ([`LoopbackPort::advance`]).

use std::time::Duration;

use firelink_host::error::{HostError, Result};
use firelink_host::port::{Dest, Port};
use firelink_wire::board::address::{
    BoardRegister, COMMAND_BLOCK_OFFSET, HUB_MEMORY_OFFSET, HUB_QUERY_OFFSET,
    REALTIME_BLOCK_OFFSET, Register,
};
use firelink_wire::board::broadcast::{HubHeader, HubPacker, HubTiming, Query, command_slices};
use firelink_wire::board::realtime::{
    BoardLayout, FirmwareRev, ReadBlockRepr, WriteBlock, WriteBlockRepr,
};
use firelink_wire::board::registers::{
    AdcWord, DAC_ZERO, EncPosition, FpgaVersion, HardwareVersion, MotorStatus, StatusCommand,
    StatusRead, Watchdog,
};

use crate::config::{DriveConfig, EncoderConfig, IoConfig, PotentiometerConfig};

/// Per-transaction virtual costs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopbackCosts {
    /// A read (quadlet or block).
    pub read: Duration,
    /// A unicast write.
    pub write: Duration,
    /// A broadcast write (non-blocking call).
    pub broadcast_write: Duration,
}

impl LoopbackCosts {
    /// Seed 000's PC-side figures.
    pub const SEED000: LoopbackCosts = LoopbackCosts {
        read: Duration::from_micros(32),
        write: Duration::from_micros(34),
        broadcast_write: Duration::from_nanos(2510),
    };
}

#[derive(Debug, Clone, Copy)]
struct Axis {
    used: bool,
    drive: DriveConfig,
    encoder: EncoderConfig,
    pot: Option<PotentiometerConfig>,
    /// Joint acceleration per amp.
    gain: f64,
    /// Viscous damping, 1/s.
    damping: f64,
    position: f64,
    velocity: f64,
    /// Encoder counts at power-up sit here: the encoder reads
    /// `position - encoder_zero`.
    encoder_zero: f64,
    dac: u16,
    amp_on: bool,
    blocked: bool,
}

impl Axis {
    fn unused() -> Axis {
        Axis {
            used: false,
            drive: DriveConfig {
                current_to_bits: crate::config::LinearFunction {
                    scale: 5242.88,
                    offset: 32768.0,
                },
                bits_to_current: crate::config::LinearFunction {
                    scale: 1.0 / 5242.88,
                    offset: -6.25,
                },
                effort_to_current: crate::config::LinearFunction {
                    scale: 1.0,
                    offset: 0.0,
                },
                maximum_current: 1.0,
            },
            encoder: EncoderConfig {
                bits_to_position: crate::config::LinearFunction {
                    scale: 1.0,
                    offset: 0.0,
                },
                position_limits_soft: crate::config::Limits {
                    lower: -1.0,
                    upper: 1.0,
                },
                velocity_source: None,
                counts_per_turn: None,
            },
            pot: None,
            gain: 0.0,
            damping: 0.0,
            position: 0.0,
            velocity: 0.0,
            encoder_zero: 0.0,
            dac: DAC_ZERO,
            amp_on: false,
            blocked: false,
        }
    }

    fn current(&self) -> f64 {
        if self.amp_on {
            self.drive.bits_to_commanded_current(self.dac)
        } else {
            0.0
        }
    }
}

#[derive(Debug, Clone)]
struct Board {
    id: u8,
    axes: [Axis; 4],
    power: bool,
    relay: bool,
    watchdog: Watchdog,
    watchdog_expired: bool,
    last_command: Duration,
    lost: bool,
    answered_seq: u16,
}

/// Boards of a configuration behind a [`Port`], without a bus. See the
/// module docs.
#[derive(Debug, Clone)]
pub struct LoopbackPort {
    boards: Vec<Board>,
    now: Duration,
    simulated_to: Duration,
    costs: LoopbackCosts,
    corrupt_queries: u32,
    last_query: Option<Query>,
    hub: Vec<u8>,
}

const LAYOUT: BoardLayout = BoardLayout::qla1(FirmwareRev::Rev8);
const PLANT_STEP: Duration = Duration::from_micros(50);

impl LoopbackPort {
    /// Rev 8 QLA1 boards for every board `config` uses, each used axis a
    /// plant tuned to its PID gains, at rest at `start(joint index)`.
    pub fn from_config(config: &IoConfig, start: impl Fn(usize) -> f64) -> LoopbackPort {
        let mut boards: Vec<Board> = config
            .boards()
            .iter()
            .map(|b| Board {
                id: b.board_id,
                axes: [Axis::unused(); 4],
                power: false,
                relay: false,
                watchdog: Watchdog::DISABLED,
                watchdog_expired: false,
                last_command: Duration::ZERO,
                lost: false,
                answered_seq: 0,
            })
            .collect();
        boards.sort_by_key(|b| b.id);
        for j in config.joints() {
            let a = j.actuator;
            let Some(board) = boards.iter_mut().find(|b| b.id == a.board_id) else {
                continue;
            };
            let Some(axis) = board.axes.get_mut(usize::from(a.axis_id)) else {
                continue;
            };
            let gains = a.simulation.and_then(|s| s.pid);
            let (kp, kd) = gains.map_or((1.0, 0.05), |g| (g.kp.abs(), g.kd.abs()));
            // Natural frequency for a damping ratio of about 0.7 with these
            // gains: w = 1.4 kp / kd, kept to 20..200 rad/s.
            let w = if kd > 0.0 { 1.4 * kp / kd } else { 60.0 }.clamp(20.0, 200.0);
            let position = start(j.index);
            *axis = Axis {
                used: true,
                drive: a.drive,
                encoder: a.encoder,
                pot: a.potentiometer,
                gain: if kp > 0.0 { w * w / kp } else { 1.0 },
                damping: 0.5,
                position,
                velocity: 0.0,
                encoder_zero: position,
                dac: DAC_ZERO,
                amp_on: false,
                blocked: false,
            };
        }
        LoopbackPort {
            boards,
            now: Duration::ZERO,
            simulated_to: Duration::ZERO,
            costs: LoopbackCosts::SEED000,
            corrupt_queries: 0,
            last_query: None,
            hub: vec![0; 2048],
        }
    }

    /// Other per-transaction costs.
    pub fn with_costs(mut self, costs: LoopbackCosts) -> LoopbackPort {
        self.costs = costs;
        self
    }

    /// Let virtual time pass without any transaction (a stopped host).
    pub fn advance(&mut self, d: Duration) {
        self.now += d;
        self.simulate();
    }

    /// The next `n` queries reach every board corrupted (boards answer with
    /// the wrong sequence number, as seed 000's 0xFFFF).
    pub fn corrupt_next_queries(&mut self, n: u32) {
        self.corrupt_queries = n;
    }

    /// Board `id` stops answering (cable pulled) or comes back.
    pub fn set_board_lost(&mut self, id: u8, lost: bool) {
        if let Some(b) = self.boards.iter_mut().find(|b| b.id == id) {
            b.lost = lost;
        }
    }

    /// Block (or free) the joint on `(board, axis)`: it stops where it is
    /// (a collision, a brake), so a moving setpoint builds a following
    /// error.
    pub fn set_axis_blocked(&mut self, board: u8, axis: usize, blocked: bool) {
        if let Some(a) = self
            .boards
            .iter_mut()
            .find(|b| b.id == board)
            .and_then(|b| b.axes.get_mut(axis))
        {
            a.blocked = blocked;
            a.velocity = 0.0;
        }
    }

    /// Whether board `id`'s watchdog has expired.
    pub fn watchdog_expired(&self, id: u8) -> bool {
        self.boards.iter().any(|b| b.id == id && b.watchdog_expired)
    }

    /// Whether any amplifier of board `id` is on.
    pub fn any_amp_on(&self, id: u8) -> bool {
        self.boards
            .iter()
            .any(|b| b.id == id && b.axes.iter().any(|a| a.amp_on))
    }

    /// True joint position of `(board, axis)` in the plant.
    pub fn plant_position(&self, board: u8, axis: usize) -> Option<f64> {
        let b = self.boards.iter().find(|b| b.id == board)?;
        b.axes.get(axis).map(|a| a.position)
    }

    fn simulate(&mut self) {
        while self.simulated_to < self.now {
            let step = (self.now - self.simulated_to).min(PLANT_STEP);
            let dt = step.as_secs_f64();
            self.simulated_to += step;
            let t = self.simulated_to;
            for b in &mut self.boards {
                if !b.watchdog.is_disabled()
                    && !b.watchdog_expired
                    && t.saturating_sub(b.last_command) > b.watchdog.period()
                {
                    b.watchdog_expired = true;
                    for a in &mut b.axes {
                        a.amp_on = false;
                    }
                }
                for a in b.axes.iter_mut().filter(|a| a.used && !a.blocked) {
                    let acc = a.gain * a.current() - a.damping * a.velocity;
                    a.velocity += acc * dt;
                    a.position += a.velocity * dt;
                }
            }
        }
    }

    fn spend(&mut self, d: Duration) {
        self.now += d;
        self.simulate();
    }

    fn board_at(&self, node: u8) -> Result<usize> {
        match self.boards.get(usize::from(node)) {
            Some(b) if !b.lost => Ok(usize::from(node)),
            _ => Err(HostError::Timeout {
                node,
                tl: 0,
                waited_us: 100,
            }),
        }
    }

    fn status(b: &Board) -> StatusRead {
        let mut amps = 0u8;
        for (i, a) in b.axes.iter().enumerate() {
            if a.amp_on {
                amps |= 1 << i;
            }
        }
        StatusRead::default()
            .with_axes(4)
            .with_board_id(b.id)
            .with_watchdog_timeout(b.watchdog_expired)
            .with_motor_supply_good(b.power)
            .with_motor_power_enabled(b.power)
            .with_relay_on(b.relay)
            .with_relay_state(b.relay)
            .with_amp_enabled(amps)
    }

    fn read_block_repr(b: &Board) -> ReadBlockRepr {
        let mut r = ReadBlockRepr::new(LAYOUT);
        r.status = Self::status(b);
        for (i, a) in b.axes.iter().enumerate() {
            let counts = a.encoder.position_to_counts(a.position - a.encoder_zero);
            let pot = a.pot.map_or(0, |p| p.position_to_bits(a.position));
            let current = a.drive.current_to_feedback_bits(a.current());
            if let Some(m) = r.motor.get_mut(i) {
                m.adc = AdcWord::default().with_pot(pot).with_current(current);
                m.status = MotorStatus::default()
                    .with_amp_on(a.amp_on)
                    .with_current_command(a.dac);
            }
            if let Some(e) = r.encoder.get_mut(i) {
                e.position = EncPosition::default().with_counts_wrapping(i64::from(counts));
            }
        }
        r
    }

    fn apply_command(&mut self, index: usize, block: &WriteBlockRepr) {
        let now = self.now;
        let Some(b) = self.boards.get_mut(index) else {
            return;
        };
        if b.lost {
            return;
        }
        b.last_command = now;
        let cmd = StatusCommand::parse(block.control.raw());
        if let Some(p) = cmd.power {
            b.power = p;
            if p {
                b.watchdog_expired = false;
            }
        }
        if let Some(r) = cmd.relay {
            b.relay = r;
        }
        for (a, d) in b.axes.iter_mut().zip(block.dacs()) {
            if d.valid() {
                a.dac = d.command();
            }
            if d.amp_enable_mask() {
                a.amp_on = d.amp_enable() && b.power && !b.watchdog_expired;
            }
        }
        if !b.power {
            for a in &mut b.axes {
                a.amp_on = false;
            }
        }
    }

    fn register(b: &Board, offset: u64) -> u32 {
        let reg = |r| Register::board(r).offset().unwrap_or(u64::MAX);
        if offset == reg(BoardRegister::Status) {
            Self::status(b).raw()
        } else if offset == reg(BoardRegister::HwVersion) {
            u32::from(HardwareVersion::Qla1)
        } else if offset == reg(BoardRegister::FwVersion) {
            8
        } else if offset == reg(BoardRegister::EthStatus) {
            FpgaVersion::V2.eth_status_bits()
        } else if offset == reg(BoardRegister::Watchdog) {
            b.watchdog.raw()
        } else {
            0
        }
    }
}

impl Port for LoopbackPort {
    fn name(&self) -> &str {
        "loopback"
    }

    fn read_quadlet(&mut self, dest: Dest, offset: u64) -> Result<u32> {
        self.spend(self.costs.read);
        let i = self.board_at(dest.node)?;
        Ok(self.boards.get(i).map_or(0, |b| Self::register(b, offset)))
    }

    fn write_quadlet(&mut self, dest: Dest, offset: u64, value: u32) -> Result<()> {
        if dest.is_broadcast() {
            self.spend(self.costs.broadcast_write);
            if offset == HUB_QUERY_OFFSET {
                let q = Query::parse(value).map_err(HostError::Wire)?;
                let mut answered = q.seq;
                if self.corrupt_queries > 0 {
                    self.corrupt_queries -= 1;
                    answered = 0xFFFF;
                }
                for b in self.boards.iter_mut().filter(|b| !b.lost) {
                    b.answered_seq = answered;
                }
                self.last_query = Some(q);
            }
            return Ok(());
        }
        self.spend(self.costs.write);
        let i = self.board_at(dest.node)?;
        let now = self.now;
        if let Some(b) = self.boards.get_mut(i) {
            if offset == Register::board(BoardRegister::Watchdog).offset()? {
                b.watchdog = Watchdog(value);
                b.last_command = now;
            } else if offset == Register::board(BoardRegister::Status).offset()? {
                let block = WriteBlockRepr {
                    control: StatusCommand::parse(value).to_word(),
                    ..WriteBlockRepr::new(LAYOUT, b.id)
                };
                self.apply_command(i, &block);
            }
        }
        Ok(())
    }

    fn read_block(&mut self, dest: Dest, offset: u64, out: &mut [u8]) -> Result<()> {
        self.spend(self.costs.read);
        let i = self.board_at(dest.node)?;
        if offset == REALTIME_BLOCK_OFFSET {
            let Some(b) = self.boards.get(i) else {
                return Err(HostError::UnknownBoard(dest.node));
            };
            Self::read_block_repr(b).emit(out)?;
            return Ok(());
        }
        if offset == HUB_MEMORY_OFFSET {
            let Some(query) = self.last_query else {
                out.fill(0);
                return Ok(());
            };
            let mut packer = HubPacker::new(&mut self.hub);
            let mut block = [0u8; 4 * 32];
            let len = LAYOUT.read_block_len();
            for (slot, b) in self.boards.iter().enumerate() {
                if !query.selects(b.id) {
                    continue;
                }
                let Some(buf) = block.get_mut(..len) else {
                    break;
                };
                // A lost board leaves its last entry (an older sequence).
                Self::read_block_repr(b).emit(buf)?;
                let header = HubHeader::Rev8 {
                    quadlets: (len / 4 + 1) as u8,
                    seq_low: b.answered_seq as u8,
                    seq_error: !b.lost && b.answered_seq != query.seq,
                    update_time: 150 + 256 * slot as u16,
                };
                packer.push(header, buf)?;
            }
            let n = packer.finish(HubTiming::default())?;
            out.fill(0);
            let m = n.min(out.len());
            if let (Some(dst), Some(src)) = (out.get_mut(..m), self.hub.get(..m)) {
                dst.copy_from_slice(src);
            }
            return Ok(());
        }
        out.fill(0);
        Ok(())
    }

    fn write_block(&mut self, dest: Dest, offset: u64, data: &[u8]) -> Result<()> {
        if dest.is_broadcast() {
            self.spend(self.costs.broadcast_write);
            if offset == COMMAND_BLOCK_OFFSET {
                for slice in command_slices(data, LAYOUT) {
                    let slice = slice?;
                    let Some(i) = self.boards.iter().position(|b| b.id == slice.board_id) else {
                        continue;
                    };
                    let repr = WriteBlock::new_checked(slice.bytes, LAYOUT)
                        .and_then(|w| WriteBlockRepr::parse(&w))?;
                    self.apply_command(i, &repr);
                }
            }
            return Ok(());
        }
        self.spend(self.costs.write);
        let i = self.board_at(dest.node)?;
        if offset == REALTIME_BLOCK_OFFSET {
            let repr =
                WriteBlock::new_checked(data, LAYOUT).and_then(|w| WriteBlockRepr::parse(&w))?;
            self.apply_command(i, &repr);
        }
        Ok(())
    }

    fn wait(&mut self, duration: Duration) {
        self.spend(duration);
    }

    fn now(&self) -> Duration {
        self.now
    }

    fn generation(&self) -> u32 {
        1
    }

    fn candidate_nodes(&self) -> core::ops::Range<u8> {
        0..self.boards.len() as u8
    }
}
