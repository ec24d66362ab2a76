//! The register file: what each address reads and what each write does
//! (`fpga-board.md` sections 1-5), and the real-time blocks.

use super::bits::{self, DigitalInBits, MotorStatusBits, PhyRequest, StatusBits};
use super::hub::HUB_QUADLETS;
use super::power::{AxisState, Watchdog};
use super::{Firmware, HUB_ADDRESS, HUB_COUNT_ADDRESS, PhyAccess, QUERY_ADDRESS};
use crate::config::Profile;
use crate::plant::{POT_FULL_SCALE_VOLTS, QLA_AMPS_PER_BIT, QLA_FULL_SCALE_AMPS};
use crate::time::Time;

/// Address spaces, bits 15:12 of the offset (section 1).
const SPACE_MAIN: u16 = 0;
const SPACE_HUB: u16 = 1;

/// Board registers, channel 0 (section 2).
mod reg {
    pub const STATUS: u8 = 0;
    pub const PHY_CTRL: u8 = 1;
    pub const PHY_DATA: u8 = 2;
    pub const WATCHDOG: u8 = 3;
    pub const HW_VERSION: u8 = 4;
    pub const TEMPERATURE: u8 = 5;
    pub const DIGITAL_OUT: u8 = 6;
    pub const FW_VERSION: u8 = 7;
    pub const DIGITAL_IN: u8 = 10;
    pub const IP_ADDR: u8 = 11;
    pub const ETH_STATUS: u8 = 12;
    pub const GIT_DESC: u8 = 15;
}

/// Axis registers, channel 1..N (section 3).
mod axis_reg {
    pub const ADC: u8 = 0;
    pub const DAC: u8 = 1;
    pub const ENC_PRELOAD: u8 = 4;
    pub const ENC_POSITION: u8 = 5;
    pub const ENC_PERIOD: u8 = 6;
    pub const ENC_QTR1: u8 = 7;
    pub const ENC_QTR5: u8 = 9;
    pub const ENC_RUN: u8 = 10;
    pub const MOTOR_CONFIG: u8 = 11;
    pub const MOTOR_STATUS: u8 = 12;
}

/// A decoded address.
enum Target {
    Board(u8),
    Axis(usize, u8),
    HubMemory(usize),
    Hub(u16),
    Unmapped,
}

fn decode(offset: u64) -> Target {
    let addr = (offset & 0xFFFF) as u16;
    match addr >> 12 {
        SPACE_MAIN if addr & 0x0F00 == 0 => {
            let channel = ((addr >> 4) & 0xF) as usize;
            let register = (addr & 0xF) as u8;
            if channel == 0 {
                Target::Board(register)
            } else {
                Target::Axis(channel - 1, register)
            }
        }
        SPACE_HUB => {
            let index = usize::from(addr - HUB_ADDRESS);
            if index < HUB_QUADLETS {
                Target::HubMemory(index)
            } else {
                Target::Hub(addr)
            }
        }
        _ => Target::Unmapped,
    }
}

/// The current-sense ADC code of a current (section 3: amps =
/// bits * 12.5 / 65536 - 6.25).
pub(crate) fn current_to_counts(amps: f64) -> u16 {
    ((amps + QLA_FULL_SCALE_AMPS) / QLA_AMPS_PER_BIT)
        .round()
        .clamp(0.0, 65535.0) as u16
}

fn pot_to_counts(volts: f64) -> u16 {
    (volts / POT_FULL_SCALE_VOLTS * 65535.0)
        .round()
        .clamp(0.0, 65535.0) as u16
}

fn temperature_byte(celsius: f64) -> u8 {
    celsius.round().clamp(0.0, 255.0) as u8
}

/// Big-endian quadlets of a byte block (a trailing partial quadlet is
/// dropped).
pub(crate) fn quadlets(bytes: &[u8]) -> Vec<u32> {
    bytes
        .chunks_exact(4)
        .map(|c| u32::from_be_bytes(c.try_into().unwrap_or([0; 4])))
        .collect()
}

impl Firmware {
    fn profile(&self) -> Profile {
        self.cfg.profile
    }

    fn n_axes(&self) -> usize {
        self.axes.len()
    }

    /// Read one quadlet at `offset` (only its low 16 bits are decoded) at
    /// `now`, as a quadlet read request would. Unmapped addresses read 0.
    pub fn read_quadlet(&mut self, now: Time, offset: u64) -> u32 {
        self.advance(now);
        match decode(offset) {
            Target::Board(r) => self.read_board_register(r),
            Target::Axis(i, r) => self.read_axis_register(i, r),
            Target::HubMemory(i) => self.hub.read(i, now),
            Target::Hub(QUERY_ADDRESS) => bits::query_word(self.hub.seq, self.hub.mask),
            Target::Hub(HUB_COUNT_ADDRESS) => self.hub.count as u32,
            Target::Hub(_) | Target::Unmapped => 0,
        }
    }

    /// Read `quadlets` quadlets from `offset` at `now`, as a block read
    /// would: address 0 is the real-time block (and restarts its
    /// timestamp), hub memory reads in arrival order, other addresses
    /// read register by register.
    pub fn read_block(&mut self, now: Time, offset: u64, quadlets: usize) -> Vec<u32> {
        self.advance(now);
        let addr = (offset & 0xFFFF) as u16;
        if addr == 0 {
            let mut block = self.sample_block(now);
            block.resize(quadlets, 0);
            return block;
        }
        (0..quadlets)
            .map(|k| {
                let a = u64::from(addr.wrapping_add(k as u16));
                match decode(a) {
                    Target::HubMemory(i) => self.hub.read(i, now),
                    _ => self.read_quadlet(now, a),
                }
            })
            .collect()
    }

    /// Write one quadlet at `offset` at `now`, as a quadlet write request
    /// addressed to this board would (refreshes the watchdog).
    pub fn write_quadlet(&mut self, now: Time, offset: u64, value: u32, phy: &mut dyn PhyAccess) {
        self.advance(now);
        self.watchdog.last_write = now;
        match decode(offset) {
            Target::Board(r) => self.write_board_register(now, r, value, phy),
            Target::Axis(i, r) => self.write_axis_register(now, i, r, value),
            Target::Hub(QUERY_ADDRESS) => self.query(now, Some(value)),
            Target::HubMemory(_) | Target::Hub(_) | Target::Unmapped => {}
        }
        self.sync_plant();
    }

    /// Write a block of quadlets at `offset` at `now`, as a block write
    /// addressed to this board would: address 0 takes a real-time write
    /// block (or this board's slice of a command block), hub memory takes
    /// a status broadcast, other addresses are written register by
    /// register.
    pub fn write_block(&mut self, now: Time, offset: u64, quads: &[u32], phy: &mut dyn PhyAccess) {
        self.advance(now);
        self.write_block_from(now, offset, quads, true, phy);
        self.sync_plant();
    }

    /// Block write; `unicast` when addressed to this node alone.
    pub(crate) fn write_block_from(
        &mut self,
        now: Time,
        offset: u64,
        quads: &[u32],
        unicast: bool,
        phy: &mut dyn PhyAccess,
    ) {
        self.watchdog.last_write = now;
        let addr = (offset & 0xFFFF) as u16;
        if addr == 0 {
            self.realtime_write(now, quads, unicast);
            return;
        }
        match decode(u64::from(addr)) {
            Target::HubMemory(_) => self.hub.store(now, quads, self.cfg.profile),
            Target::Hub(QUERY_ADDRESS) => {
                if let Some(&w) = quads.first() {
                    self.query(now, Some(w));
                }
            }
            Target::Board(_) | Target::Axis(..) => {
                for (k, &q) in quads.iter().enumerate() {
                    let a = u64::from(addr.wrapping_add(k as u16));
                    match decode(a) {
                        Target::Board(r) => self.write_board_register(now, r, q, phy),
                        Target::Axis(i, r) => self.write_axis_register(now, i, r, q),
                        _ => {}
                    }
                }
            }
            Target::Hub(_) | Target::Unmapped => {}
        }
    }

    /// A block write to address 0: a real-time write block, or a command
    /// block of concatenated write blocks from which this board takes the
    /// slice naming it (sections 5 and 6.5).
    fn realtime_write(&mut self, now: Time, quads: &[u32], unicast: bool) {
        let own = self.cfg.write_block_quadlets();
        let id = self.cfg.board_id;
        if self.profile().is_rev8() {
            let mut pos = 0;
            while let Some(&header) = quads.get(pos) {
                let (board, len) = bits::write_header(header);
                if len == 0 {
                    break;
                }
                if board == id {
                    if let Some(slice) = quads.get(pos..pos + len) {
                        self.apply_write_block(now, slice);
                    }
                    return;
                }
                pos += len;
            }
        } else if unicast && quads.len() == own {
            self.apply_write_block(now, quads);
        } else {
            // Rev 7 blocks carry no header: the board ID sits in bits
            // 27:24 of the DAC quadlets.
            if let Some(slice) = quads
                .chunks_exact(own)
                .find(|b| b.first().is_some_and(|&d| bits::dac(d).board_id == id))
            {
                self.apply_write_block(now, slice);
            }
        }
    }

    /// Apply one board's write block (header included on Rev 8).
    fn apply_write_block(&mut self, now: Time, block: &[u32]) {
        let body = if self.profile().is_rev8() {
            block.get(1..).unwrap_or(&[])
        } else {
            block
        };
        let m = self.n_axes();
        for (i, &word) in body.iter().take(m).enumerate() {
            self.dac_write(now, i, word);
        }
        if let Some(&control) = body.get(m) {
            let control = control & bits::BLOCK_CONTROL_BITS;
            if control != 0 {
                self.status_write(now, control);
            }
        }
    }

    fn read_board_register(&self, r: u8) -> u32 {
        match r {
            reg::STATUS => self.status_word(),
            reg::PHY_CTRL => self.phy_ctrl,
            reg::PHY_DATA => self.phy_data,
            reg::WATCHDOG => u32::from(self.watchdog.ticks),
            reg::HW_VERSION => self.cfg.hardware.hw_version(),
            reg::TEMPERATURE => self.temperature_word(),
            reg::DIGITAL_OUT => u32::from(self.dout),
            reg::FW_VERSION => self.profile().firmware_version(),
            reg::DIGITAL_IN => self.digital_in_word(),
            reg::IP_ADDR if self.cfg.fpga.has_ethernet() => self.ip_addr,
            reg::ETH_STATUS => self.cfg.fpga.eth_status(),
            reg::GIT_DESC => self.cfg.git_desc,
            _ => 0,
        }
    }

    fn write_board_register(&mut self, now: Time, r: u8, value: u32, phy: &mut dyn PhyAccess) {
        match r {
            reg::STATUS => self.status_write(now, value),
            reg::PHY_CTRL => {
                self.phy_ctrl = value;
                match bits::phy_ctrl(value) {
                    PhyRequest::Read(register) => {
                        let data = phy.read_phy_register(register);
                        self.phy_data = bits::phy_data(register, data);
                    }
                    PhyRequest::Write(register, data) => phy.write_phy_register(register, data),
                }
            }
            reg::WATCHDOG => self.watchdog.ticks = value as u16,
            reg::DIGITAL_OUT => {
                let (mask, levels) = bits::digital_out(value);
                self.dout = (self.dout & !mask) | levels;
            }
            reg::IP_ADDR if self.cfg.fpga.has_ethernet() => self.ip_addr = value,
            _ => {}
        }
    }

    fn read_axis_register(&mut self, i: usize, r: u8) -> u32 {
        let Some(a) = self.axes.get(i) else {
            return 0;
        };
        let rev8 = self.profile().is_rev8();
        match r {
            axis_reg::ADC => self.adc_word(i),
            axis_reg::DAC => u32::from(a.command),
            axis_reg::ENC_PRELOAD => a.preload,
            axis_reg::ENC_POSITION => self.position_word(i),
            axis_reg::ENC_PERIOD => self.velocity(i).map_or(0, |f| bits::enc_period(f.period)),
            axis_reg::ENC_QTR1 => self.velocity(i).map_or(0, |f| bits::enc_quarter(f.qtr1)),
            axis_reg::ENC_QTR5 => self.velocity(i).map_or(0, |f| bits::enc_quarter(f.qtr5)),
            axis_reg::ENC_RUN => self.velocity(i).map_or(0, |f| bits::enc_run(f.run)),
            axis_reg::MOTOR_CONFIG if rev8 => bits::motor_config_read(
                bits::MotorConfig {
                    enable_delay: a.enable_delay,
                    current_limit: a.current_limit,
                },
                true,
            ),
            axis_reg::MOTOR_STATUS if rev8 => self.motor_status_word(i),
            _ => 0,
        }
    }

    fn write_axis_register(&mut self, now: Time, i: usize, r: u8, value: u32) {
        if i >= self.n_axes() {
            return;
        }
        let raw = self.raw_count(i);
        let rev8 = self.profile().is_rev8();
        match r {
            axis_reg::DAC => self.dac_write(now, i, value),
            axis_reg::ENC_PRELOAD => {
                if let Some(a) = self.axes.get_mut(i) {
                    a.preload = value & bits::ENC_COUNT_MASK;
                    a.count_offset = i64::from(a.preload) - raw;
                    a.overflow = false;
                }
            }
            axis_reg::MOTOR_CONFIG if rev8 => {
                let c = bits::motor_config_write(value);
                if let Some(a) = self.axes.get_mut(i) {
                    a.enable_delay = c.enable_delay;
                    a.current_limit = c.current_limit;
                }
            }
            _ => {}
        }
    }

    /// A DAC word (register or write block): command if valid, and on
    /// Rev 8 the amplifier request of bits 29:28.
    fn dac_write(&mut self, now: Time, i: usize, word: u32) {
        let d = bits::dac(word);
        if let Some(a) = self.axes.get_mut(i)
            && d.valid
        {
            a.command = d.command;
        }
        if self.profile().is_rev8()
            && let Some(enable) = d.amp_request
        {
            self.request_amplifier(now, i, enable);
        }
    }

    /// The host asks for amplifier `i` on or off. Asking for on clears the
    /// watchdog flag and the axis's safety disable; it takes effect only
    /// with motor power enabled.
    fn request_amplifier(&mut self, now: Time, i: usize, enable: bool) {
        if enable {
            self.watchdog.timed_out = false;
        }
        let power_on = self.power.enabled;
        let Some(a) = self.axes.get_mut(i) else {
            return;
        };
        if enable {
            a.safety_disabled = false;
            a.mismatch_since = None;
            if power_on && !a.requested {
                a.requested = true;
                a.requested_since = now;
            }
        } else {
            a.requested = false;
        }
    }

    /// A STATUS write (section 2): power, relay, amplifiers, reboot.
    fn status_write(&mut self, now: Time, word: u32) {
        let cmd = bits::status_write(word);
        if cmd.reboot {
            self.reboot(now);
            return;
        }
        match cmd.power {
            Some(true) => {
                self.watchdog.timed_out = false;
                for a in &mut self.axes {
                    a.safety_disabled = false;
                    a.mismatch_since = None;
                }
                self.power.enabled = true;
            }
            Some(false) => {
                self.power.enabled = false;
                for a in &mut self.axes {
                    a.requested = false;
                }
            }
            None => {}
        }
        self.power.update_supply(now);
        if let Some(relay) = cmd.relay {
            self.power.relay = relay;
        }
        for i in 0..4 {
            if cmd.amp_mask & (1 << i) != 0 {
                self.request_amplifier(now, i, cmd.amp_enable & (1 << i) != 0);
            }
        }
    }

    /// Reboot (STATUS `0x00300000`): every register back to its power-up
    /// value; the plant keeps moving.
    fn reboot(&mut self, now: Time) {
        self.power = super::Power::new(self.power.supply_present, self.cfg.supply_rise);
        self.watchdog = Watchdog::new(now);
        self.axes = self
            .plant
            .axes()
            .iter()
            .map(|a| AxisState::new(a.encoder().count()))
            .collect();
        self.phy_ctrl = 0;
        self.phy_data = 0;
        self.dout = 0;
        self.ip_addr = 0;
        self.last_sample = now;
        self.hub = super::Hub::new();
    }

    fn raw_count(&self, i: usize) -> i64 {
        self.plant.axis(i).map_or(0, |a| a.encoder().count())
    }

    fn velocity(&self, i: usize) -> Option<crate::plant::encoder::VelocityFields> {
        self.plant.axis(i).map(|a| a.encoder().fields(self.now))
    }

    fn status_word(&self) -> u32 {
        let now = self.now;
        let mut amp_enabled = 0u8;
        let mut amp_on = 0u8;
        let mut safety = 0u8;
        for (i, a) in self.axes.iter().take(4).enumerate() {
            amp_enabled |= u8::from(a.requested) << i;
            amp_on |= u8::from(a.is_on(&self.power, now)) << i;
            safety |= u8::from(a.safety_disabled) << i;
        }
        bits::status_read(StatusBits {
            axes: self.n_axes() as u8,
            board_id: self.cfg.board_id,
            watchdog_timeout: self.watchdog.timed_out,
            quad_dac: true,
            supply_good: self.power.supply_good(now),
            power_enabled: self.power.enabled,
            relay_state: self.power.relay,
            relay_on: self.power.relay,
            supply_fault: self.power.supply_fault(),
            safety_feedback: self.power.relay,
            io_expander: true,
            amp_status: if self.profile().is_rev8() { 0 } else { amp_on },
            safety_amp_disable: safety,
            amp_enabled,
        })
    }

    fn temperature_word(&self) -> u32 {
        // One sensor per pair of amplifiers: the hotter of the two.
        let pair = |k: usize| {
            let t = self
                .plant
                .axes()
                .iter()
                .skip(2 * k)
                .take(2)
                .map(|a| a.temperature())
                .fold(f64::MIN, f64::max);
            temperature_byte(if t == f64::MIN { 0.0 } else { t })
        };
        let low = bits::temperature(pair(0), pair(1));
        if self.n_axes() > 4 {
            low | (bits::temperature(pair(2), pair(3)) << 16)
        } else {
            low
        }
    }

    fn digital_in_word(&self) -> u32 {
        let mut d = DigitalInBits {
            v_fault: self.power.supply_fault(),
            outputs: self.dout,
            ..DigitalInBits::default()
        };
        for (i, axis) in self.plant.axes().iter().take(4).enumerate() {
            let enc = axis.encoder();
            let (neg, pos, home) = axis.switches();
            d.enc_a |= u8::from(enc.a()) << i;
            d.enc_b |= u8::from(enc.b()) << i;
            d.index |= u8::from(enc.index()) << i;
            d.neg_limits |= u8::from(neg) << i;
            d.pos_limits |= u8::from(pos) << i;
            d.home |= u8::from(home) << i;
        }
        bits::digital_in(d)
    }

    fn adc_word(&self, i: usize) -> u32 {
        bits::adc(
            pot_to_counts(self.plant.measured_pot(i)),
            current_to_counts(self.plant.measured_current(i)),
        )
    }

    fn position_word(&mut self, i: usize) -> u32 {
        let raw = self.raw_count(i);
        let lines = self
            .plant
            .axis(i)
            .map(|a| (a.encoder().index(), a.encoder().b(), a.encoder().a()));
        let rev8 = self.profile().is_rev8();
        let Some(a) = self.axes.get_mut(i) else {
            return 0;
        };
        let count = raw + a.count_offset;
        if !(0..=i64::from(bits::ENC_COUNT_MASK)).contains(&count) {
            a.overflow = true;
        }
        bits::enc_position(
            (count & i64::from(bits::ENC_COUNT_MASK)) as u32,
            a.overflow,
            if rev8 { lines } else { None },
        )
    }

    fn motor_status_word(&self, i: usize) -> u32 {
        let Some(a) = self.axes.get(i) else {
            return 0;
        };
        bits::motor_status(MotorStatusBits {
            amp_on: a.is_on(&self.power, self.now),
            amp_requested: a.requested,
            safety_disable: a.safety_disabled,
            amp_fault: false,
            command: a.command,
        })
    }

    /// Sample the real-time read block at `now` (section 4) and restart
    /// the timestamp.
    pub(crate) fn sample_block(&mut self, now: Time) -> Vec<u32> {
        let timestamp = now.clocks().wrapping_sub(self.last_sample.clocks()) as u32;
        self.last_sample = now;
        let n = self.n_axes();
        let mut block = Vec::with_capacity(self.cfg.read_block_quadlets());
        block.push(timestamp);
        block.push(self.status_word());
        block.push(self.digital_in_word());
        block.push(self.temperature_word());
        block.extend((0..n).map(|i| self.adc_word(i)));
        let positions: Vec<u32> = (0..n).map(|i| self.position_word(i)).collect();
        block.extend(positions);
        let fields: Vec<_> = (0..n)
            .map(|i| self.velocity(i).unwrap_or_default())
            .collect();
        block.extend(fields.iter().map(|f| bits::enc_period(f.period)));
        block.extend(fields.iter().map(|f| bits::enc_quarter(f.qtr1)));
        block.extend(fields.iter().map(|f| bits::enc_quarter(f.qtr5)));
        block.extend(fields.iter().map(|f| bits::enc_run(f.run)));
        if self.profile().is_rev8() {
            block.extend((0..n).map(|i| self.motor_status_word(i)));
        }
        block
    }
}
