//! The Snake node's FPGA as a bus-agnostic state machine: link rules,
//! the register map of Table 1, the real-time blocks, the digital pots'
//! SPI commands, the watchdog, and the plant behind the seven channels.
//!
//! Link behaviour (seed 001 §6.1, §6.4):
//! - Only packets whose destination is this node's ID are acted on; a
//!   broadcast, another node's packet or a tcode other than quadlet/block
//!   read/write is silently ignored (counted).
//! - A packet whose header or data CRC fails is silently dropped.
//! - Reads are concatenated (`ack_pending` and the response at once),
//!   writes unified (`ack_complete` means done).
//! - Every write addressed to the node clears the watchdog counter.
//!
//! Firelink's choices where the seed leaves room (each deliberate):
//! - A quadlet read of a cell Table 1 lists as not implemented, or of an
//!   address outside it, is answered with `resp_address_error`; a block
//!   read at an offset other than 0 too. Writes to read-only or unmapped
//!   cells, and register words that do not decode, get `ack_type_error`
//!   and change nothing.
//! - Block reads of any size up to 512 quadlets are served (the seed's
//!   firmware accepts any size, §6.1): the first quadlets are the 23 of
//!   the block, the rest zeros. A block write of a size other than 7
//!   quadlets is acknowledged and ignored (counted); a 7-quadlet block
//!   with a malformed quadlet gets `ack_type_error` and is not applied at
//!   all, never half.
//! - A digital-pot command takes 20 us on the SPI bus (an EEPROM write
//!   2 ms); meanwhile the channel's ADC holds its last sample (a read) or
//!   its DAC writes wait (a write), and another pot command is answered
//!   `ack_busy_X`. EEPROM writes while write-protected finish with the
//!   result's error bit.
//! - The watchdog is off at power-up; when it expires every amplifier is
//!   disabled and STATUS bit 23 is set until a STATUS write turns an
//!   amplifier back on (writes that only turn amplifiers off keep it).
//! - A channel's fault line (injected, or the amplifier above
//!   [`AmplifierModel::fault_celsius`]) clears its enable; it cannot be
//!   enabled while the line is asserted.
//! - The ADC converts continuously, every 2 us (§6.2: "roughly 2 us"):
//!   the node's plant integrates on that grid (its default step), so a
//!   read returns the last conversion, a sample of the plant at most 2 us
//!   old with fresh noise.

use firelink_wire::packet::{Ack, AsyncHeader, NodeId, Packet, PacketRepr, Rcode, Tcode};
use firelink_wire::qla::registers::{PhyData, PhyRequest};
use firelink_wire::snake::address::{ChannelDevice, GlobalRegister, SnakeRegister};
use firelink_wire::snake::block::{
    READ_BLOCK_QUADLETS, ReadBlockRepr, WRITE_BLOCK_LEN, WriteBlock, WriteBlockRepr,
};
use firelink_wire::snake::registers::{
    AdcData, DAC_MIDPOINT, DacCommand, DacReadback, EncoderPreload, PotCommand, PotResult,
    PowerControl, SnakeStatus,
};
use firelink_wire::snake::{BLOCK_OFFSET, CHANNELS, MAX_BLOCK_QUADLETS};

use super::channel::{
    AmplifierModel, DigitalPot, EncoderCounter, period_register, volts_to_sample,
};
use super::config::SnakeNodeConfig;
use crate::plant::{DAC_ZERO, Plant};
use crate::qla::power::Watchdog;
use crate::qla::{PhyAccess, Reply, block_read_refusal, block_response_packet, emit};
use crate::time::{SimDuration, SimTime};

/// Time of one digital-pot SPI command.
pub const POT_SPI_TIME: SimDuration = SimDuration::from_micros(20);
/// Time of an EEPROM write in the digital pot.
pub const EEPROM_WRITE_TIME: SimDuration = SimDuration::from_millis(2);

/// What the node counted about the packets it saw.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SnakeNodeStats {
    /// Packets seen (every packet on the bus reaches every node).
    pub packets: u64,
    /// Not addressed to this node (other nodes, broadcasts): ignored.
    pub not_addressed: u64,
    /// Addressed here with a tcode the node does not support: ignored.
    pub unsupported_tcode: u64,
    /// Header CRC failures: dropped.
    pub header_crc: u64,
    /// Data CRC failures: dropped.
    pub data_crc: u64,
    /// Quadlet reads served.
    pub quadlet_reads: u64,
    /// Quadlet writes taken.
    pub quadlet_writes: u64,
    /// Block reads served.
    pub block_reads: u64,
    /// Block writes applied.
    pub block_writes: u64,
    /// Block writes of another size than 7 quadlets: acknowledged, ignored.
    pub wrong_size_block_writes: u64,
    /// Requests refused (address error, type error, busy).
    pub refused: u64,
}

/// A digital-pot command on the SPI bus.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct PotJob {
    command: PotCommand,
    done_at: SimTime,
}

/// State of one channel.
#[derive(Debug, Clone, PartialEq)]
struct Channel {
    dac_voltage: u16,
    dac_limit: u16,
    /// A motor DAC write waiting for a pot write to finish.
    dac_deferred: Option<u16>,
    pot: DigitalPot,
    pot_word: u32,
    pot_result: PotResult,
    pot_job: Option<PotJob>,
    /// The ADC sample held while a pot read pauses conversions.
    adc_hold: Option<AdcData>,
    encoder: EncoderCounter,
    injected_fault: bool,
    fault_line: bool,
}

/// One emulated Snake node.
#[derive(Debug, Clone)]
pub struct SnakeFirmware {
    cfg: SnakeNodeConfig,
    plant: Plant,
    now: SimTime,
    phy_id: Option<u8>,
    generation: u32,
    phy_ctrl: u32,
    phy_data: PhyData,
    watchdog: Watchdog,
    amp_enable: u8,
    enable_mask: u8,
    channels: Vec<Channel>,
    last_block_read: SimTime,
    stats: SnakeNodeStats,
    rx_error: Option<&'static str>,
}

/// Amperes per drive code of the plant's current-driven axis model.
fn amps_per_code(model: &AmplifierModel) -> f64 {
    model.max_amps / 32767.0
}

impl SnakeFirmware {
    /// A node freshly powered up at time zero: amplifiers off, DACs at the
    /// midpoint with a zero current limit, pots as configured, encoders
    /// at 0, watchdog off, no node ID until the first bus reset.
    pub fn new(cfg: SnakeNodeConfig) -> SnakeFirmware {
        let model = cfg.amplifier;
        let axes = cfg
            .plant_axes()
            .into_iter()
            .map(|mut p| {
                p.amplifier.amps_per_bit = amps_per_code(&model);
                p.amplifier.current_limit = model.max_amps;
                p.amplifier.supply_voltage = model.supply_volts;
                p
            })
            .collect();
        let plant = Plant::new(axes, cfg.seed, cfg.plant_step);
        let channels = (0..CHANNELS)
            .map(|i| Channel {
                dac_voltage: DAC_MIDPOINT,
                dac_limit: 0,
                dac_deferred: None,
                pot: cfg.pots.get(i).cloned().unwrap_or_default(),
                pot_word: 0,
                pot_result: PotResult::default(),
                pot_job: None,
                adc_hold: None,
                encoder: EncoderCounter::preloaded(
                    plant.axis(i).map_or(0, |a| a.encoder().count()),
                    0,
                ),
                injected_fault: false,
                fault_line: false,
            })
            .collect();
        SnakeFirmware {
            plant,
            now: SimTime::ZERO,
            phy_id: None,
            generation: 0,
            phy_ctrl: 0,
            phy_data: PhyData::default(),
            watchdog: Watchdog {
                ticks: 0,
                led_select: false,
                last_write: SimTime::ZERO,
                timed_out: false,
            },
            amp_enable: 0,
            enable_mask: 0,
            channels,
            last_block_read: SimTime::ZERO,
            stats: SnakeNodeStats::default(),
            rx_error: None,
            cfg,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &SnakeNodeConfig {
        &self.cfg
    }

    /// The rotary-switch board ID.
    pub fn board_id(&self) -> u8 {
        self.cfg.board_id
    }

    /// The physical ID from the last bus reset.
    pub fn phy_id(&self) -> Option<u8> {
        self.phy_id
    }

    /// The time the state corresponds to.
    pub fn now(&self) -> SimTime {
        self.now
    }

    /// The plant.
    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// The plant, e.g. to push on an axis.
    pub fn plant_mut(&mut self) -> &mut Plant {
        &mut self.plant
    }

    /// Packet counters.
    pub fn stats(&self) -> SnakeNodeStats {
        self.stats
    }

    /// The damage noticed in the last packet, if any (cleared by this call
    /// and by every [`receive`](Self::receive)).
    pub fn take_rx_error(&mut self) -> Option<&'static str> {
        self.rx_error.take()
    }

    /// Whether channel `channel`'s (1..=7) amplifier is enabled.
    pub fn amplifier_on(&self, channel: u8) -> bool {
        channel_index(channel).is_some_and(|i| self.amp_enable & (1 << i) != 0)
    }

    /// The motor DAC code applied on channel `channel` (1..=7).
    pub fn motor_command(&self, channel: u8) -> Option<u16> {
        self.channel(channel).map(|c| c.dac_voltage)
    }

    /// Channel `channel`'s digital pot (1..=7).
    pub fn pot(&self, channel: u8) -> Option<&DigitalPot> {
        self.channel(channel).map(|c| &c.pot)
    }

    /// STATUS bit 23.
    pub fn watchdog_timed_out(&self) -> bool {
        self.watchdog.timed_out
    }

    /// When the watchdog fires if nothing is written before.
    pub fn watchdog_expiry(&self) -> Option<SimTime> {
        self.watchdog.expiry()
    }

    /// When the node next changes by itself (watchdog, a pot command
    /// finishing): the bus node sets a timer for it.
    pub fn next_wakeup(&self) -> Option<SimTime> {
        let pot = self
            .channels
            .iter()
            .filter_map(|c| c.pot_job.map(|j| j.done_at))
            .min();
        [self.watchdog.expiry(), pot].into_iter().flatten().min()
    }

    /// Assert or release channel `channel`'s amplifier fault line at
    /// `now` (fault injection).
    pub fn set_fault(&mut self, now: SimTime, channel: u8, asserted: bool) {
        self.advance(now);
        if let Some(c) = channel_index(channel).and_then(|i| self.channels.get_mut(i)) {
            c.injected_fault = asserted;
        }
        self.update_faults();
    }

    fn channel(&self, channel: u8) -> Option<&Channel> {
        channel_index(channel).and_then(|i| self.channels.get(i))
    }

    /// A bus reset gave this node physical ID `phy_id`; registers are kept.
    pub fn bus_reset(&mut self, now: SimTime, phy_id: u8, generation: u32) {
        self.advance(now);
        self.phy_id = Some(phy_id & 0x3F);
        self.generation = generation;
    }

    /// Let time pass up to `now`: the plant integrates, the watchdog and
    /// pot commands take effect at their exact times. Earlier times are
    /// ignored.
    pub fn advance(&mut self, now: SimTime) {
        while self.now < now {
            let target = self
                .next_wakeup()
                .filter(|t| *t > self.now && *t <= now)
                .unwrap_or(now);
            self.integrate_to(target);
            self.now = target;
            self.process_events();
        }
    }

    /// Integrate the plant to `target`, recomputing the amplifier drives
    /// every sub-step while a channel drives in speed mode (its current
    /// depends on the motor's state), once otherwise.
    fn integrate_to(&mut self, target: SimTime) {
        let speed_mode = self
            .channels
            .iter()
            .enumerate()
            .any(|(i, c)| c.pot.outputs.speed_mode && self.amp_enable & (1 << i) != 0);
        if speed_mode {
            let step = self.plant.step().0;
            while self.plant.time().0.saturating_add(step) <= target.0 {
                self.apply_drives();
                let next = SimTime(self.plant.time().0 + step);
                self.plant.advance_to(next);
            }
        } else {
            self.apply_drives();
            self.plant.advance_to(target);
        }
        for (i, c) in self.channels.iter_mut().enumerate() {
            if let Some(a) = self.plant.axis(i) {
                c.encoder.observe(a.encoder().count());
            }
        }
        self.update_faults();
    }

    /// Hand each axis the current its amplifier drives now.
    fn apply_drives(&mut self) {
        let model = self.cfg.amplifier;
        let per_code = amps_per_code(&model);
        for (i, c) in self.channels.iter().enumerate() {
            let enabled = self.amp_enable & (1 << i) != 0;
            let Some(axis) = self.plant.axis_mut(i) else {
                continue;
            };
            let gain = c.pot.wiper.feedback_gain();
            let amps = if c.pot.outputs.speed_mode {
                let motor = &axis.params().motor;
                model.speed_amps(
                    c.dac_voltage,
                    gain,
                    axis.current(),
                    motor.torque_constant * axis.motor_velocity(),
                    motor.resistance,
                )
            } else {
                model.torque_amps(c.dac_voltage, gain)
            };
            let limit = model.limit_amps(c.dac_limit);
            let amps = if amps.is_finite() {
                amps.clamp(-limit, limit)
            } else {
                0.0
            };
            let code = (f64::from(DAC_ZERO) + amps / per_code)
                .round()
                .clamp(0.0, 65535.0) as u16;
            axis.set_drive(code, enabled);
        }
    }

    /// Apply what is due at `self.now`: watchdog expiry, finished pot
    /// commands.
    fn process_events(&mut self) {
        let now = self.now;
        if self.watchdog.expiry().is_some_and(|t| now >= t) {
            self.watchdog.timed_out = true;
            self.amp_enable = 0;
        }
        for i in 0..self.channels.len() {
            let due = self
                .channels
                .get(i)
                .and_then(|c| c.pot_job)
                .filter(|j| j.done_at <= now);
            if let Some(job) = due {
                self.finish_pot(i, job.command);
            }
        }
    }

    /// The fault lines now; a faulted channel's enable is cleared.
    fn update_faults(&mut self) {
        let limit = self.cfg.amplifier.fault_celsius;
        for (i, c) in self.channels.iter_mut().enumerate() {
            let hot = self.plant.axis(i).is_some_and(|a| a.temperature() >= limit);
            c.fault_line = c.injected_fault || hot;
            if c.fault_line {
                self.amp_enable &= !(1 << i);
            }
        }
    }

    fn fault_lines(&self) -> u8 {
        self.channels
            .iter()
            .enumerate()
            .filter(|(_, c)| c.fault_line)
            .fold(0, |m, (i, _)| m | (1 << i))
    }

    /// STATUS (Table 2) now.
    pub fn status(&self) -> SnakeStatus {
        SnakeStatus::default()
            .with_board_id(self.cfg.board_id)
            .with_watchdog_timeout(self.watchdog.timed_out)
            .with_faults(self.fault_lines())
            .with_enable_mask(self.enable_mask)
            .with_amp_enable(self.amp_enable)
    }

    /// Channel `i`'s (0-based) ADC data now.
    fn adc(&self, i: usize) -> AdcData {
        if let Some(held) = self.channels.get(i).and_then(|c| c.adc_hold) {
            return held;
        }
        let pot = volts_to_sample(self.plant.measured_pot(i) - 1.25);
        let current = self
            .cfg
            .amplifier
            .monitor_sample(self.plant.measured_current(i));
        AdcData::from_signed(pot, current)
    }

    fn encoder_raw(&self, i: usize) -> i64 {
        self.plant.axis(i).map_or(0, |a| a.encoder().count())
    }

    /// Read the register at `offset` at `now`, as a quadlet read would.
    ///
    /// # Errors
    /// [`Rcode::AddressError`] for an address Table 1 does not list or
    /// lists as not implemented.
    pub fn read_quadlet(&mut self, now: SimTime, offset: u64) -> Result<u32, Rcode> {
        self.advance(now);
        let r = SnakeRegister::from_offset(offset).map_err(|_| Rcode::AddressError)?;
        if !r.access().readable() {
            return Err(Rcode::AddressError);
        }
        Ok(match r {
            SnakeRegister::Global(g) => match g {
                GlobalRegister::Status => self.status().raw(),
                GlobalRegister::PhyControl => self.phy_ctrl,
                GlobalRegister::PhyData => self.phy_data.raw(),
                GlobalRegister::WatchdogPeriod => u32::from(self.watchdog.ticks),
                GlobalRegister::Version => self.cfg.version,
            },
            SnakeRegister::Channel { channel, device } => {
                let i = usize::from(channel) - 1;
                let Some(c) = self.channels.get(i) else {
                    return Err(Rcode::AddressError);
                };
                match device {
                    ChannelDevice::Adc => self.adc(i).raw(),
                    ChannelDevice::Dac => DacReadback::default()
                        .with_current_limit(c.dac_limit)
                        .with_motor_voltage(c.dac_voltage)
                        .raw(),
                    ChannelDevice::PotControl => c.pot_word,
                    ChannelDevice::PotData => c.pot_result.raw(),
                    ChannelDevice::EncoderPreload => c.encoder.preload,
                    ChannelDevice::EncoderData => c.encoder.data(self.encoder_raw(i)).raw(),
                    ChannelDevice::EncoderPeriod => self
                        .plant
                        .axis(i)
                        .map_or(0, |a| period_register(&a.encoder().fields(now)).raw()),
                    ChannelDevice::EncoderFrequency => return Err(Rcode::AddressError),
                }
            }
        })
    }

    /// Write the register at `offset` at `now`, as a quadlet write
    /// addressed to this node would (the watchdog counter is cleared
    /// whatever the outcome). Returns the ack.
    pub fn write_quadlet(
        &mut self,
        now: SimTime,
        offset: u64,
        value: u32,
        phy: &mut dyn PhyAccess,
    ) -> Ack {
        self.advance(now);
        self.watchdog.last_write = now;
        let Ok(r) = SnakeRegister::from_offset(offset) else {
            return Ack::TypeError;
        };
        if !r.access().writable() {
            return Ack::TypeError;
        }
        match r {
            SnakeRegister::Global(g) => match g {
                GlobalRegister::Status => {
                    let p = PowerControl(value);
                    self.enable_mask = p.mask();
                    self.amp_enable = p.apply(self.amp_enable) & !self.fault_lines();
                    // Turning an amplifier back on acknowledges the time-out.
                    if p.mask() & p.enable() != 0 {
                        self.watchdog.timed_out = false;
                    }
                }
                GlobalRegister::PhyControl => match PhyRequest::parse(value) {
                    Ok(PhyRequest::Read { register }) => {
                        self.phy_ctrl = value;
                        let data = phy.read_phy_register(register);
                        self.phy_data = PhyData::default().with_register(register).with_data(data);
                    }
                    Ok(PhyRequest::Write { register, data }) => {
                        self.phy_ctrl = value;
                        phy.write_phy_register(register, data);
                    }
                    Err(_) => return Ack::TypeError,
                },
                GlobalRegister::WatchdogPeriod => {
                    let Ok(ticks) = u16::try_from(value) else {
                        return Ack::TypeError;
                    };
                    self.watchdog.ticks = ticks;
                }
                GlobalRegister::PhyData | GlobalRegister::Version => return Ack::TypeError,
            },
            SnakeRegister::Channel { channel, device } => {
                let i = usize::from(channel) - 1;
                let raw = self.encoder_raw(i);
                let sample = self.adc(i);
                let Some(c) = self.channels.get_mut(i) else {
                    return Ack::TypeError;
                };
                match device {
                    ChannelDevice::Dac => match DacCommand::parse(value) {
                        Ok(DacCommand::MotorVoltage(v)) => c.set_motor(v),
                        Ok(DacCommand::CurrentLimit(v)) => c.dac_limit = v,
                        Err(_) => return Ack::TypeError,
                    },
                    ChannelDevice::PotControl => {
                        if c.pot_job.is_some() {
                            return Ack::BusyX;
                        }
                        let Ok(command) = PotCommand::parse(value) else {
                            return Ack::TypeError;
                        };
                        c.start_pot(now, value, command, sample);
                    }
                    ChannelDevice::EncoderPreload => match EncoderPreload::parse(value) {
                        Ok(p) => c.encoder = EncoderCounter::preloaded(raw, p.count()),
                        Err(_) => return Ack::TypeError,
                    },
                    _ => return Ack::TypeError,
                }
            }
        }
        Ack::Complete
    }

    fn finish_pot(&mut self, i: usize, command: PotCommand) {
        let Some(c) = self.channels.get_mut(i) else {
            return;
        };
        let mut error = false;
        let data = match command {
            PotCommand::ReadWiper => c.pot.wiper.value(),
            PotCommand::WriteWiper(w) => {
                c.pot.wiper = w;
                w.value()
            }
            PotCommand::ReadEeprom(word) => {
                c.pot.eeprom.get(usize::from(word)).copied().unwrap_or(0)
            }
            PotCommand::WriteEeprom { word, value } => {
                match c.pot.eeprom.get_mut(usize::from(word)) {
                    Some(slot) if !c.pot.write_protect => *slot = value,
                    _ => error = true,
                }
                value
            }
            PotCommand::ReadOutputs => c.pot.outputs.bits(),
            PotCommand::WriteOutputs(o) => {
                c.pot.outputs = o;
                o.bits()
            }
            PotCommand::ReadWriteProtect => u16::from(c.pot.write_protect),
            PotCommand::WriteProtect(on) => {
                c.pot.write_protect = on;
                u16::from(on)
            }
        };
        c.pot_result = c
            .pot_result
            .with_busy(false)
            .with_ready(true)
            .with_error(error)
            .with_data(data);
        c.pot_job = None;
        c.adc_hold = None;
        if let Some(v) = c.dac_deferred.take() {
            c.dac_voltage = v;
        }
    }

    /// The block read at `now` (its timestamp restarts).
    pub fn block_read(&mut self, now: SimTime) -> ReadBlockRepr {
        self.advance(now);
        let mut block = ReadBlockRepr {
            status: self.status(),
            timestamp: now.clocks_since(self.last_block_read) as u32,
            ..ReadBlockRepr::default()
        };
        self.last_block_read = now;
        for (i, ch) in block.channels.iter_mut().enumerate() {
            ch.adc = self.adc(i);
            ch.encoder = self
                .channels
                .get(i)
                .map(|c| c.encoder.data(self.encoder_raw(i)))
                .unwrap_or_default();
            ch.period = self
                .plant
                .axis(i)
                .map(|a| period_register(&a.encoder().fields(now)))
                .unwrap_or_default();
        }
        block
    }

    /// Apply a block write's data at `now` (watchdog cleared). Returns
    /// the ack.
    pub fn block_write(&mut self, now: SimTime, data: &[u8]) -> Ack {
        self.advance(now);
        self.watchdog.last_write = now;
        if data.len() != WRITE_BLOCK_LEN {
            self.stats.wrong_size_block_writes += 1;
            return Ack::Complete;
        }
        let Ok(block) = WriteBlock::new_checked(data).and_then(|b| WriteBlockRepr::parse(&b))
        else {
            self.stats.refused += 1;
            return Ack::TypeError;
        };
        for (c, command) in self.channels.iter_mut().zip(block.commands) {
            if let Some(v) = command {
                c.set_motor(v);
            }
        }
        self.stats.block_writes += 1;
        Ack::Complete
    }

    /// Handle one packet as it arrived at `now` (CRCs are checked here).
    pub fn receive(&mut self, now: SimTime, bytes: &[u8], phy: &mut dyn PhyAccess) -> Reply {
        self.advance(now);
        self.rx_error = None;
        self.stats.packets += 1;
        let Ok(packet) = Packet::new_checked(bytes) else {
            self.stats.not_addressed += 1;
            return Reply::Silent;
        };
        let tcode = packet.tcode();
        let dest = packet.destination_id();
        let mine = tcode.has_header_crc()
            && dest.bus() == NodeId::LOCAL_BUS
            && self.phy_id == Some(dest.phy())
            && !dest.is_broadcast();
        if !mine {
            self.stats.not_addressed += 1;
            return Reply::Silent;
        }
        if packet.header_crc_ok() != Some(true) {
            self.stats.header_crc += 1;
            self.rx_error = Some("header CRC error: packet dropped");
            return Reply::Silent;
        }
        let offset = packet.offset();
        let header = AsyncHeader {
            destination: packet.source_id(),
            source: NodeId::local(self.phy_id.unwrap_or(0)),
            tl: packet.tl(),
            rt: 0,
            pri: 0,
        };
        let reply = match tcode {
            Tcode::WriteQuadletRequest => {
                self.stats.quadlet_writes += 1;
                Reply::Ack(self.write_quadlet(now, offset, packet.quadlet_data(), phy))
            }
            Tcode::WriteBlockRequest => {
                if packet.data_crc_ok() != Some(true) {
                    self.stats.data_crc += 1;
                    self.rx_error = Some("data CRC error: packet dropped");
                    return Reply::Silent;
                }
                if offset != BLOCK_OFFSET {
                    self.watchdog.last_write = now;
                    Reply::Ack(Ack::TypeError)
                } else {
                    Reply::Ack(self.block_write(now, packet.data()))
                }
            }
            Tcode::ReadQuadletRequest => {
                self.stats.quadlet_reads += 1;
                let (rcode, data) = match self.read_quadlet(now, offset) {
                    Ok(v) => (Rcode::Complete, v),
                    Err(rcode) => (rcode, 0),
                };
                Reply::AckThenResponse {
                    ack: Ack::Pending,
                    response: emit(&PacketRepr::ReadQuadletResponse {
                        header,
                        rcode,
                        data,
                    }),
                }
            }
            Tcode::ReadBlockRequest => Reply::AckThenResponse {
                ack: Ack::Pending,
                response: self.block_read_response(now, header, offset, packet.data_length()),
            },
            _ => {
                self.stats.unsupported_tcode += 1;
                return Reply::Silent;
            }
        };
        if matches!(
            reply,
            Reply::Ack(Ack::TypeError | Ack::BusyX | Ack::DataError)
        ) {
            self.stats.refused += 1;
        }
        reply
    }

    fn block_read_response(
        &mut self,
        now: SimTime,
        header: AsyncHeader,
        offset: u64,
        length: u16,
    ) -> Vec<u8> {
        let length = usize::from(length);
        let refusal = block_read_refusal(length, 4 * MAX_BLOCK_QUADLETS)
            .or((offset != BLOCK_OFFSET).then_some(Rcode::AddressError));
        if let Some(rcode) = refusal {
            self.stats.refused += 1;
            return block_response_packet(header, rcode, &[]);
        }
        self.stats.block_reads += 1;
        let block = self.block_read(now);
        let mut data = vec![0u8; length.max(4 * READ_BLOCK_QUADLETS)];
        // The buffer holds at least the whole block: emitting cannot fail.
        let _ = block.emit(&mut data);
        data.truncate(length);
        block_response_packet(header, Rcode::Complete, &data)
    }
}

impl Channel {
    /// A motor DAC write: applied at once, or after a running pot write.
    fn set_motor(&mut self, value: u16) {
        let pot_writing = self.pot_job.is_some_and(|j| j.command.is_write());
        if pot_writing {
            self.dac_deferred = Some(value);
        } else {
            self.dac_voltage = value;
        }
    }

    fn start_pot(&mut self, now: SimTime, word: u32, command: PotCommand, sample: AdcData) {
        let duration = if matches!(command, PotCommand::WriteEeprom { .. }) {
            EEPROM_WRITE_TIME
        } else {
            POT_SPI_TIME
        };
        self.pot_word = word;
        self.pot_result = PotResult::default()
            .with_busy(true)
            .with_op_bits(u8::from(command.op()))
            .with_address(command.address());
        self.pot_job = Some(PotJob {
            command,
            done_at: now + duration,
        });
        if !command.is_write() {
            self.adc_hold = Some(sample);
        }
    }
}

/// The 0-based index of channel `channel` (1..=7).
fn channel_index(channel: u8) -> Option<usize> {
    (1..=CHANNELS as u8)
        .contains(&channel)
        .then(|| usize::from(channel) - 1)
}
