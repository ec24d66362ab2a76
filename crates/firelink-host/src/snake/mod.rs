//! Seed 001's API for its Snake robot nodes, the three layers of Fig. 18:
//!
//! 1. the abstract robot I/O ([`RobotIo`], implemented here for
//!    [`SnakeSystem`]: the same trait the QLA boards implement);
//! 2. the node layer ([`SnakeNodeIo`]): each node's local buffers, filled
//!    by one block read, emptied by one block write whose quadlets carry a
//!    valid bit per channel;
//! 3. the bus layer: any [`Port`] (the simulated bus, the UDP bridge).
//!
//! Real-time data (feedback and motor commands) moves in the blocks; the
//! rest of the Get/Set list are quadlet transactions done at once: the
//! current limit (the dual DAC's second channel, written apart from the
//! motor command), the encoder preload, the digital pot's wiper, outputs
//! (the torque/speed switch), write protection and EEPROM, the power
//! control word and the watchdog. The seed's conventions hold: ADC
//! values come with 8192 added (0..=16383), DAC codes are unsigned with
//! the midpoint at 0 V, an EEPROM index carries the channel in bits 7-4
//! and the word in bits 3-0, a float takes two EEPROM words.
//!
//! | seed 001 | here |
//! |---|---|
//! | `GetStatus`, `GetTimestamp` | [`SnakeNodeIo::status`], [`SnakeNodeIo::timestamp`] |
//! | `GetMotorCurrent`, `GetAnalogPosition` | [`SnakeNodeIo::motor_current`], [`SnakeNodeIo::analog_position`] |
//! | `GetEncoderPosition`, `GetEncoderVelocity` | [`SnakeNodeIo::encoder_position`], [`SnakeNodeIo::encoder_period`] |
//! | `GetDigitalPotWiper`, `SetDigitalPotWiper` | [`SnakeSystem::digital_pot_wiper`], [`SnakeSystem::set_digital_pot_wiper`] |
//! | `GetAnalogSwitches`, `SetAnalogSwitches` | [`SnakeSystem::analog_switches`], [`SnakeSystem::set_analog_switches`] |
//! | `GetEepromDataRaw`, `SetEepromDataRaw` | [`SnakeSystem::eeprom_raw`], [`SnakeSystem::set_eeprom_raw`] |
//! | `GetEepromDataFloat`, `SetEepromDataFloat` | [`SnakeSystem::eeprom_float`], [`SnakeSystem::set_eeprom_float`] |
//! | `SetPowerControl` | [`SnakeSystem::set_power_control`] |
//! | `SetMotorVoltage` | [`SnakeNodeIo::set_motor_voltage`] |
//! | `SetMotorCurrent` (the limit) | [`SnakeSystem::set_motor_current`] |
//! | `SetEncoderPreload` | [`SnakeSystem::set_encoder_preload`] |
//! | `LatchAllInputs`, `ApplyAllOutputs` | [`SnakeSystem::latch_all_inputs`], [`SnakeSystem::apply_all_outputs`] |

mod node;

pub use node::{EepromIndex, SnakeNodeInfo, SnakeNodeIo, channel, float_to_words, words_to_float};

use std::time::Duration;

use firelink_wire::packet::Ack;
use firelink_wire::qla::registers::{Watchdog, WatchdogSetting};
use firelink_wire::snake::address::{ChannelDevice, GlobalRegister, SnakeRegister};
use firelink_wire::snake::block::{READ_BLOCK_LEN, ReadBlock, ReadBlockRepr, WRITE_BLOCK_LEN};
use firelink_wire::snake::registers::{
    DacCommand, DacReadback, ENCODER_MIDPOINT, EncoderPreload, PotCommand, PotOutputs, PotResult,
    PowerControl, SnakeStatus, Wiper, is_snake_version,
};
use firelink_wire::snake::{BLOCK_OFFSET, CHANNELS};

use crate::cycle_report::{CycleReport, IoStats};
use crate::error::{HostError, MissReason, Result};
use crate::port::{Dest, Port};
use crate::robot_io::{RobotIo, bad_axis};

/// How long a digital-pot command may take before the host gives up
/// (an EEPROM write takes milliseconds).
pub const POT_TIMEOUT: Duration = Duration::from_millis(50);
/// The host's first wait after issuing a pot command (one SPI frame).
const POT_FIRST_WAIT: Duration = Duration::from_micros(25);
/// Then it polls the result this often.
const POT_POLL: Duration = Duration::from_micros(250);

/// Snake nodes behind a port, driven as one robot I/O system.
pub struct SnakeSystem<P: Port> {
    port: P,
    nodes: Vec<SnakeNodeIo>,
    report: CycleReport,
    stats: IoStats,
    buf: [u8; READ_BLOCK_LEN],
    cmd: [u8; WRITE_BLOCK_LEN],
    needs_rescan: bool,
    /// Nodes this system asked for an amplifier since the last power-down.
    energised: u16,
    /// The watchdog this system last programmed.
    watchdog: Option<WatchdogSetting>,
}

/// Find the Snake nodes behind `port`: every candidate node whose version
/// register carries the Snake signature, with the board ID from its
/// STATUS, by ascending board ID. Other boards on the bus (a QLA answers
/// the same quadlet with its hardware version) and silent nodes are
/// skipped.
///
/// # Errors
/// [`HostError::NoBoards`] when no Snake node answered; a duplicate board
/// ID as [`HostError::InvalidRequest`].
pub fn discover<P: Port>(port: &mut P) -> Result<Vec<SnakeNodeInfo>> {
    let version = SnakeRegister::Global(GlobalRegister::Version).offset();
    let status = SnakeRegister::Global(GlobalRegister::Status).offset();
    let mut found: Vec<SnakeNodeInfo> = Vec::new();
    for node in port.candidate_nodes() {
        let Ok(v) = port.read_quadlet(Dest::node(node), version) else {
            continue;
        };
        if !is_snake_version(v) {
            continue;
        }
        let s = SnakeStatus(port.read_quadlet(Dest::node(node), status)?);
        if found.iter().any(|n| n.board_id == s.board_id()) {
            return Err(HostError::InvalidRequest {
                what: "two Snake nodes have the same board ID (rotary switch)",
                value: u32::from(s.board_id()),
            });
        }
        found.push(SnakeNodeInfo {
            board_id: s.board_id(),
            node,
            version: v,
        });
    }
    if found.is_empty() {
        return Err(HostError::NoBoards {
            seen: port.link_stats(),
        });
    }
    found.sort_by_key(|n| n.board_id);
    Ok(found)
}

impl<P: Port> SnakeSystem<P> {
    /// Discover the nodes behind `port` and set up their buffers.
    ///
    /// # Errors
    /// As [`discover`].
    pub fn open(mut port: P) -> Result<SnakeSystem<P>> {
        let nodes = discover(&mut port)?;
        Ok(SnakeSystem {
            port,
            nodes: nodes.into_iter().map(SnakeNodeIo::new).collect(),
            report: CycleReport::EMPTY,
            stats: IoStats::default(),
            buf: [0; READ_BLOCK_LEN],
            cmd: [0; WRITE_BLOCK_LEN],
            needs_rescan: false,
            energised: 0,
            watchdog: None,
        })
    }

    /// The port.
    pub fn port(&self) -> &P {
        &self.port
    }

    /// The port, mutable.
    pub fn port_mut(&mut self) -> &mut P {
        &mut self.port
    }

    /// The nodes, by ascending board ID.
    pub fn nodes(&self) -> &[SnakeNodeIo] {
        &self.nodes
    }

    /// The node with board ID `board_id`.
    pub fn node(&self, board_id: u8) -> Option<&SnakeNodeIo> {
        self.nodes.iter().find(|n| n.board_id() == board_id)
    }

    /// The node with board ID `board_id`, mutable (to set its outputs).
    pub fn node_mut(&mut self, board_id: u8) -> Option<&mut SnakeNodeIo> {
        self.nodes.iter_mut().find(|n| n.board_id() == board_id)
    }

    /// The last cycle's report.
    pub fn report(&self) -> &CycleReport {
        &self.report
    }

    /// Counters over all cycles.
    pub fn stats(&self) -> &IoStats {
        &self.stats
    }

    /// Whether a bus reset asks for [`rescan`](Self::rescan).
    pub fn needs_rescan(&self) -> bool {
        self.needs_rescan
    }

    /// Find the nodes again (after a bus reset: node numbers may have
    /// moved); buffers of nodes still present are kept.
    ///
    /// # Errors
    /// As [`discover`].
    pub fn rescan(&mut self) -> Result<()> {
        let found = discover(&mut self.port)?;
        let mut nodes: Vec<SnakeNodeIo> = Vec::with_capacity(found.len());
        for info in found {
            let mut n = self
                .nodes
                .iter()
                .find(|n| n.board_id() == info.board_id)
                .cloned()
                .unwrap_or_else(|| SnakeNodeIo::new(info));
            n.set_info(info);
            nodes.push(n);
        }
        self.nodes = nodes;
        self.needs_rescan = false;
        Ok(())
    }

    fn note_error(&mut self, e: HostError) {
        if self.report.note_error(&mut self.stats, e) {
            self.needs_rescan = true;
        }
    }

    fn miss(&mut self, index: usize, reason: MissReason) {
        let Some(node) = self.nodes.get_mut(index) else {
            return;
        };
        node.invalidate();
        let id = node.board_id();
        self.report.note_miss(&mut self.stats, id, reason);
    }

    /// `LatchAllInputs`: one block read per node. Never fails as a whole:
    /// misses (by board ID, with the reason) and errors are in the report
    /// and the stats; a node that missed has its inputs marked invalid.
    pub fn latch_all_inputs(&mut self) -> &CycleReport {
        let cycle = self.report.cycle + 1;
        self.report = CycleReport::EMPTY;
        self.report.cycle = cycle;
        self.stats.cycles += 1;
        self.port.begin_cycle();
        let started = self.port.now();
        self.report.started = started;
        for i in 0..self.nodes.len() {
            let Some(info) = self.nodes.get(i).map(|n| *n.info()) else {
                break;
            };
            if self.needs_rescan {
                self.miss(i, MissReason::Transaction);
                continue;
            }
            let read = self
                .port
                .read_block(Dest::node(info.node), BLOCK_OFFSET, &mut self.buf);
            if let Err(e) = read {
                self.miss(i, MissReason::Transaction);
                self.note_error(e);
                continue;
            }
            let parsed =
                ReadBlock::new_checked(&self.buf[..]).and_then(|b| ReadBlockRepr::parse(&b));
            match parsed {
                Ok(block) if block.status.board_id() != info.board_id => self.miss(
                    i,
                    MissReason::WrongBoardId {
                        found: block.status.board_id(),
                    },
                ),
                Ok(block) => {
                    if let Some(n) = self.nodes.get_mut(i) {
                        n.latch(block);
                    }
                }
                Err(e) => {
                    self.miss(i, MissReason::NotUpdated);
                    self.note_error(HostError::Wire(e));
                }
            }
        }
        self.report.read_time = self.port.now().saturating_sub(started);
        if self.report.all_ok() {
            self.stats.clean_cycles += 1;
        }
        &self.report
    }

    /// `ApplyAllOutputs`: per node, the buffered power-control word (if
    /// any) as a quadlet write, then the block write with a valid bit on
    /// every channel set since the last apply. Valid bits and power
    /// requests are cleared afterwards.
    pub fn apply_all_outputs(&mut self) -> &CycleReport {
        let started = self.port.now();
        let status = SnakeRegister::Global(GlobalRegister::Status).offset();
        for i in 0..self.nodes.len() {
            let Some(node) = self.nodes.get(i) else {
                break;
            };
            if self.needs_rescan {
                break;
            }
            let dest = Dest::node(node.info().node);
            let power = node.pending_power();
            if power.is_some_and(|p| p.enable() & p.mask() != 0) {
                self.energised |= 1 << (node.board_id() & 0xF);
            }
            let emitted = node.output().emit(&mut self.cmd);
            if let Some(p) = power {
                if let Err(e) = self.port.write_quadlet(dest, status, p.raw()) {
                    self.note_error(e);
                }
            }
            match emitted {
                Ok(_) => {
                    if let Err(e) = self.port.write_block(dest, BLOCK_OFFSET, &self.cmd) {
                        self.note_error(e);
                    }
                }
                Err(e) => self.note_error(HostError::Wire(e)),
            }
        }
        for n in &mut self.nodes {
            n.outputs_applied();
        }
        self.report.write_time = self.port.now().saturating_sub(started);
        self.port.end_cycle();
        &self.report
    }

    fn dest(&self, board_id: u8) -> Result<Dest> {
        self.node(board_id)
            .map(|n| Dest::node(n.info().node))
            .ok_or(HostError::UnknownBoard(board_id))
    }

    /// Read one register of a node (a quadlet read, at once).
    ///
    /// # Errors
    /// [`HostError::UnknownBoard`]; port errors (an unimplemented cell
    /// answers `resp_address_error`).
    pub fn read_register(&mut self, board_id: u8, register: SnakeRegister) -> Result<u32> {
        let dest = self.dest(board_id)?;
        self.port.read_quadlet(dest, register.offset())
    }

    /// Write one register of a node (a quadlet write, at once).
    ///
    /// # Errors
    /// [`HostError::UnknownBoard`]; port errors (a refused word answers
    /// `ack_type_error`).
    pub fn write_register(
        &mut self,
        board_id: u8,
        register: SnakeRegister,
        value: u32,
    ) -> Result<()> {
        let dest = self.dest(board_id)?;
        self.port.write_quadlet(dest, register.offset(), value)
    }

    fn channel_register(ch: u8, device: ChannelDevice) -> Result<SnakeRegister> {
        SnakeRegister::channel(channel(ch)?, device).map_err(|_| node::bad_channel(ch))
    }

    /// `SetPowerControl`: amplifier enables with their mask, at once.
    ///
    /// # Errors
    /// As [`write_register`](Self::write_register).
    pub fn set_power_control(&mut self, board_id: u8, control: PowerControl) -> Result<()> {
        self.write_register(
            board_id,
            SnakeRegister::Global(GlobalRegister::Status),
            control.raw(),
        )
    }

    /// `SetMotorCurrent`: the current limit (the DAC's second channel), at
    /// once.
    ///
    /// # Errors
    /// [`HostError::InvalidRequest`] for a channel outside 1..=7; as
    /// [`write_register`](Self::write_register).
    pub fn set_motor_current(&mut self, board_id: u8, ch: u8, code: u16) -> Result<()> {
        let r = Self::channel_register(ch, ChannelDevice::Dac)?;
        self.write_register(board_id, r, DacCommand::CurrentLimit(code).to_word())
    }

    /// The motor command and current limit a channel's DAC holds.
    ///
    /// # Errors
    /// As [`set_motor_current`](Self::set_motor_current).
    pub fn dac(&mut self, board_id: u8, ch: u8) -> Result<DacReadback> {
        let r = Self::channel_register(ch, ChannelDevice::Dac)?;
        self.read_register(board_id, r).map(DacReadback)
    }

    /// `SetEncoderPreload`: the count the encoder takes now (0..=0xFFFFFF;
    /// the overflow flag clears).
    ///
    /// # Errors
    /// [`HostError::InvalidRequest`] for a channel outside 1..=7 or a
    /// count above 24 bits; as [`write_register`](Self::write_register).
    pub fn set_encoder_preload(&mut self, board_id: u8, ch: u8, count: u32) -> Result<()> {
        let r = Self::channel_register(ch, ChannelDevice::EncoderPreload)?;
        let p = EncoderPreload::new(count).map_err(|_| HostError::InvalidRequest {
            what: "encoder preload (0..=0xFFFFFF)",
            value: count,
        })?;
        self.write_register(board_id, r, p.to_word())
    }

    /// Reset a channel's encoder to the midpoint, as the seed recommends.
    ///
    /// # Errors
    /// As [`set_encoder_preload`](Self::set_encoder_preload).
    pub fn reset_encoder(&mut self, board_id: u8, ch: u8) -> Result<()> {
        self.set_encoder_preload(board_id, ch, ENCODER_MIDPOINT)
    }

    /// Run one digital-pot command to completion: wait while the pot is
    /// busy, write the command, poll the result until it is ready.
    ///
    /// # Errors
    /// [`HostError::InvalidRequest`] for a channel outside 1..=7 or an
    /// EEPROM write the pot refused (write protection);
    /// [`HostError::Timeout`] after [`POT_TIMEOUT`]; port errors.
    pub fn pot_command(&mut self, board_id: u8, ch: u8, command: PotCommand) -> Result<u16> {
        let dest = self.dest(board_id)?;
        let control = Self::channel_register(ch, ChannelDevice::PotControl)?.offset();
        let data = Self::channel_register(ch, ChannelDevice::PotData)?.offset();
        let start = self.port.now();
        let timed_out = |port: &P| {
            (port.now().saturating_sub(start) > POT_TIMEOUT).then(|| HostError::Timeout {
                node: dest.node,
                tl: 0,
                waited_us: POT_TIMEOUT.as_micros() as u32,
            })
        };
        // A command still running from someone else: let it finish.
        while PotResult(self.port.read_quadlet(dest, data)?).busy() {
            if let Some(e) = timed_out(&self.port) {
                return Err(e);
            }
            self.port.wait(POT_POLL);
        }
        loop {
            match self.port.write_quadlet(dest, control, command.to_word()) {
                Ok(()) => break,
                Err(HostError::Ack {
                    ack: Ack::BusyX | Ack::BusyA | Ack::BusyB,
                    ..
                }) => {
                    if let Some(e) = timed_out(&self.port) {
                        return Err(e);
                    }
                    self.port.wait(POT_POLL);
                }
                Err(e) => return Err(e),
            }
        }
        self.port.wait(POT_FIRST_WAIT);
        loop {
            let r = PotResult(self.port.read_quadlet(dest, data)?);
            if r.ready() && !r.busy() && r.op() == command.op() && r.address() == command.address()
            {
                if r.error() {
                    return Err(HostError::InvalidRequest {
                        what: "EEPROM write refused: the channel's write protection is on",
                        value: u32::from(command.address()),
                    });
                }
                return Ok(r.data());
            }
            if let Some(e) = timed_out(&self.port) {
                return Err(e);
            }
            self.port.wait(POT_POLL);
        }
    }

    /// `GetDigitalPotWiper`.
    ///
    /// # Errors
    /// As [`pot_command`](Self::pot_command).
    pub fn digital_pot_wiper(&mut self, board_id: u8, ch: u8) -> Result<Wiper> {
        let w = self.pot_command(board_id, ch, PotCommand::ReadWiper)?;
        Wiper::new(w).map_err(HostError::Wire)
    }

    /// `SetDigitalPotWiper`: 0..=1023.
    ///
    /// # Errors
    /// [`HostError::InvalidRequest`] above 1023; as
    /// [`pot_command`](Self::pot_command).
    pub fn set_digital_pot_wiper(&mut self, board_id: u8, ch: u8, wiper: u16) -> Result<()> {
        let w = Wiper::new(wiper).map_err(|_| HostError::InvalidRequest {
            what: "digital pot wiper (0..=1023)",
            value: u32::from(wiper),
        })?;
        self.pot_command(board_id, ch, PotCommand::WriteWiper(w))
            .map(|_| ())
    }

    /// `GetAnalogSwitches`: the pot's digital outputs (O1: speed mode).
    ///
    /// # Errors
    /// As [`pot_command`](Self::pot_command).
    pub fn analog_switches(&mut self, board_id: u8, ch: u8) -> Result<PotOutputs> {
        let bits = self.pot_command(board_id, ch, PotCommand::ReadOutputs)?;
        PotOutputs::from_bits(bits).map_err(HostError::Wire)
    }

    /// `SetAnalogSwitches`.
    ///
    /// # Errors
    /// As [`pot_command`](Self::pot_command).
    pub fn set_analog_switches(&mut self, board_id: u8, ch: u8, outputs: PotOutputs) -> Result<()> {
        self.pot_command(board_id, ch, PotCommand::WriteOutputs(outputs))
            .map(|_| ())
    }

    /// Whether the channel's EEPROM is write-protected.
    ///
    /// # Errors
    /// As [`pot_command`](Self::pot_command).
    pub fn write_protect(&mut self, board_id: u8, ch: u8) -> Result<bool> {
        self.pot_command(board_id, ch, PotCommand::ReadWriteProtect)
            .map(|v| v != 0)
    }

    /// Set or clear the channel's EEPROM write protection.
    ///
    /// # Errors
    /// As [`pot_command`](Self::pot_command).
    pub fn set_write_protect(&mut self, board_id: u8, ch: u8, on: bool) -> Result<()> {
        self.pot_command(board_id, ch, PotCommand::WriteProtect(on))
            .map(|_| ())
    }

    /// `GetEepromDataRaw`: `index` bits 7-4 the channel, 3-0 the word.
    ///
    /// # Errors
    /// [`HostError::InvalidRequest`] for a bad index; as
    /// [`pot_command`](Self::pot_command).
    pub fn eeprom_raw(&mut self, board_id: u8, index: u32) -> Result<u16> {
        let at = EepromIndex::from_index(index)?;
        self.pot_command(board_id, at.channel, PotCommand::ReadEeprom(at.word))
    }

    /// `SetEepromDataRaw`.
    ///
    /// # Errors
    /// As [`eeprom_raw`](Self::eeprom_raw); a write-protected EEPROM.
    pub fn set_eeprom_raw(&mut self, board_id: u8, index: u32, value: u16) -> Result<()> {
        let at = EepromIndex::from_index(index)?;
        self.pot_command(
            board_id,
            at.channel,
            PotCommand::WriteEeprom {
                word: at.word,
                value,
            },
        )
        .map(|_| ())
    }

    /// `GetEepromDataFloat`: the float in words `index` and `index + 1`.
    ///
    /// # Errors
    /// As [`eeprom_raw`](Self::eeprom_raw); a first word above 12.
    pub fn eeprom_float(&mut self, board_id: u8, index: u32) -> Result<f32> {
        let at = EepromIndex::from_index(index)?;
        let second = at.next()?;
        let hi = self.eeprom_raw(board_id, at.index())?;
        let lo = self.eeprom_raw(board_id, second.index())?;
        Ok(words_to_float([hi, lo]))
    }

    /// `SetEepromDataFloat`: split into two words at the library level.
    ///
    /// # Errors
    /// As [`eeprom_float`](Self::eeprom_float); a write-protected EEPROM.
    pub fn set_eeprom_float(&mut self, board_id: u8, index: u32, value: f32) -> Result<()> {
        let at = EepromIndex::from_index(index)?;
        let second = at.next()?;
        let [hi, lo] = float_to_words(value);
        self.set_eeprom_raw(board_id, at.index(), hi)?;
        self.set_eeprom_raw(board_id, second.index(), lo)
    }

    /// The watchdog period of one node.
    ///
    /// # Errors
    /// As [`read_register`](Self::read_register).
    pub fn watchdog(&mut self, board_id: u8) -> Result<Duration> {
        let w = self.read_register(
            board_id,
            SnakeRegister::Global(GlobalRegister::WatchdogPeriod),
        )?;
        Ok(Watchdog(w & 0xFFFF).period())
    }

    /// Program every node's watchdog (off only as
    /// [`WatchdogSetting::Off`]).
    ///
    /// # Errors
    /// Port errors.
    pub fn set_watchdog(&mut self, setting: WatchdogSetting) -> Result<()> {
        let word = setting.register();
        self.watchdog = Some(setting);
        let register = SnakeRegister::Global(GlobalRegister::WatchdogPeriod);
        for i in 0..self.nodes.len() {
            let Some(id) = self.nodes.get(i).map(|n| n.board_id()) else {
                break;
            };
            self.write_register(id, register, word.raw())?;
        }
        Ok(())
    }

    /// Tell each node in `boards` (bit i = board ID i) directly to disable
    /// every amplifier; the nodes that acknowledged (none over a port
    /// whose writes are not acknowledged).
    pub fn disable_amplifiers_acknowledged(&mut self, boards: u16) -> u16 {
        let acknowledged = self.port.acknowledges_writes();
        let mut confirmed = 0u16;
        for i in 0..self.nodes.len() {
            let Some(id) = self.nodes.get(i).map(|n| n.board_id()) else {
                break;
            };
            if boards & (1 << id) == 0 || self.needs_rescan {
                continue;
            }
            match self.set_power_control(id, PowerControl::all(false)) {
                Ok(()) if acknowledged => confirmed |= 1 << id,
                Ok(()) => {}
                Err(e) => self.note_error(e),
            }
        }
        confirmed
    }

    /// (node index, channel 1..=7) of a flat axis number.
    fn locate(&self, axis: usize) -> Result<(usize, u8)> {
        let node = axis / CHANNELS;
        if node >= self.nodes.len() {
            return Err(bad_axis(axis));
        }
        Ok((node, (axis % CHANNELS) as u8 + 1))
    }

    fn node_at(&self, axis: usize) -> Result<(&SnakeNodeIo, u8)> {
        let (n, ch) = self.locate(axis)?;
        let node = self.nodes.get(n).ok_or_else(|| bad_axis(axis))?;
        Ok((node, ch))
    }

    fn node_at_mut(&mut self, axis: usize) -> Result<(&mut SnakeNodeIo, u8)> {
        let (n, ch) = self.locate(axis)?;
        let node = self.nodes.get_mut(n).ok_or_else(|| bad_axis(axis))?;
        Ok((node, ch))
    }
}

/// The Snake nodes as abstract robot I/O: every node has seven axes (its
/// channels 1-7 are axes 0-6 of the board); there is no switched motor
/// supply, so a node is powered whenever it answers.
impl<P: Port> RobotIo for SnakeSystem<P> {
    fn port_name(&self) -> &str {
        self.port.name()
    }

    fn now(&self) -> Duration {
        self.port.now()
    }

    fn wait(&mut self, duration: Duration) {
        self.port.wait(duration);
    }

    fn boards(&self) -> u16 {
        self.nodes
            .iter()
            .fold(0, |m, n| m | (1 << (n.board_id() & 0xF)))
    }

    fn axis_count(&self) -> usize {
        self.nodes.len() * CHANNELS
    }

    fn axis_index(&self, board_id: u8, axis: u8) -> Option<usize> {
        let n = self.nodes.iter().position(|n| n.board_id() == board_id)?;
        (usize::from(axis) < CHANNELS).then_some(n * CHANNELS + usize::from(axis))
    }

    fn axis_location(&self, axis: usize) -> Option<(u8, u8)> {
        let (node, ch) = self.node_at(axis).ok()?;
        Some((node.board_id(), ch - 1))
    }

    fn latch_all_inputs(&mut self) -> &CycleReport {
        SnakeSystem::latch_all_inputs(self)
    }

    fn apply_all_outputs(&mut self) -> &CycleReport {
        SnakeSystem::apply_all_outputs(self)
    }

    fn stats(&self) -> &IoStats {
        &self.stats
    }

    fn board_answered(&self, board_id: u8) -> bool {
        self.node(board_id).is_some_and(|n| n.is_valid())
    }

    fn powered(&self, board_id: u8) -> bool {
        self.board_answered(board_id)
    }

    fn watchdog_expired(&self, board_id: u8) -> bool {
        self.node(board_id)
            .is_some_and(|n| n.status().watchdog_timeout())
    }

    fn timestamp(&self, board_id: u8) -> Option<u32> {
        self.node(board_id)
            .filter(|n| n.is_valid())
            .map(|n| n.timestamp())
    }

    fn set_power(&mut self, boards: u16, on: bool) {
        if !on {
            for n in &mut self.nodes {
                if boards & (1 << (n.board_id() & 0xF)) != 0 {
                    n.set_all_amplifiers(false);
                }
            }
        }
    }

    fn set_watchdog(&mut self, setting: WatchdogSetting) -> Result<()> {
        SnakeSystem::set_watchdog(self, setting)
    }

    fn energised(&self) -> u16 {
        self.energised
    }

    fn clear_energised(&mut self) {
        self.energised = 0;
    }

    fn watchdog_programmed(&self) -> Option<WatchdogSetting> {
        self.watchdog
    }

    fn switches_power(&self) -> bool {
        false
    }

    fn disable_amplifiers_acknowledged(&mut self, boards: u16) -> u16 {
        SnakeSystem::disable_amplifiers_acknowledged(self, boards)
    }

    fn recover(&mut self) -> Result<()> {
        if self.needs_rescan {
            self.rescan()?;
        }
        Ok(())
    }

    fn encoder_position(&self, axis: usize) -> Result<i32> {
        let (n, ch) = self.node_at(axis)?;
        n.encoder_counts(ch)
    }

    fn encoder_velocity(&self, axis: usize) -> Result<f64> {
        let (n, ch) = self.node_at(axis)?;
        n.encoder_velocity(ch)
    }

    fn analog_position(&self, axis: usize) -> Result<u16> {
        let (n, ch) = self.node_at(axis)?;
        n.analog_position(ch)
    }

    fn motor_current(&self, axis: usize) -> Result<u16> {
        let (n, ch) = self.node_at(axis)?;
        n.motor_current(ch)
    }

    fn amplifier_enabled(&self, axis: usize) -> Result<bool> {
        let (n, ch) = self.node_at(axis)?;
        Ok(n.is_valid() && n.amplifier_enabled(ch)?)
    }

    fn set_motor_command(&mut self, axis: usize, code: u16) -> Result<()> {
        let (n, ch) = self.node_at_mut(axis)?;
        n.set_motor_voltage(ch, code)
    }

    fn set_amplifier_enable(&mut self, axis: usize, on: bool) -> Result<()> {
        let (n, ch) = self.node_at_mut(axis)?;
        n.set_amplifier_enable(ch, on)
    }

    fn set_all_safe(&mut self) {
        for n in &mut self.nodes {
            n.safe_outputs();
        }
    }
}

/// As [`IoSystem`](crate::qla::io::IoSystem)'s: a program that enabled
/// amplifiers and ends without a power-down gets one
/// ([`RobotIo::power_down`]).
impl<P: Port> Drop for SnakeSystem<P> {
    fn drop(&mut self) {
        if self.energised != 0 {
            let _ = RobotIo::power_down(self);
        }
    }
}
