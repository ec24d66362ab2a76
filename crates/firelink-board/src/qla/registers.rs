//! The register file: what each address reads and what each write does
//! (`fpga-board.md` sections 1-5), and the real-time blocks.

use firelink_wire::field;
use firelink_wire::qla::address::{
    Address, AddressSpace, AxisRegister, BoardRegister, HubAddress, REALTIME_BLOCK_OFFSET, Register,
};
use firelink_wire::qla::broadcast::find_command_block;
use firelink_wire::qla::dqla::{DqlaDigitalIn, DqlaStatus};
use firelink_wire::qla::extras::{
    DallasControl, EthControl, ExpanderWrite, PromCommand, QlaPromCommand,
};
use firelink_wire::qla::fpga_v3::{EthControlV3, mdio_port_of};
use firelink_wire::qla::realtime::{
    BlockFormat, BoardLayout, EncoderReading, MotorReading, ReadBlock, WriteBlock,
};
use firelink_wire::qla::registers::{
    AdcWord, DacWord, DigitalIn, DigitalOutWrite, DoutCtrl, ENC_NEUTRAL, EncPeriod, EncPosition,
    EncQuarter, EncRun, FpgaVersion, MotorConfig, MotorStatus, PhyData, PhyRequest, StatusCommand,
    StatusRead, StatusWrite, Temperature, Watchdog as WatchdogWord,
};

use super::config::{Hardware, Profile};
use super::dout::OUTPUTS;
use super::dqla_expander::{DqlaExpanders, PortLines};
use super::expander::ExpanderInputs;
use super::power::{AxisState, Watchdog};
use super::{Firmware, PhyAccess, RxError};
use crate::plant::encoder::{PeriodField, QuarterField, RunField, VelocityFields};
use crate::plant::{POT_FULL_SCALE_VOLTS, QLA_AMPS_PER_BIT, QLA_FULL_SCALE_AMPS};
use crate::time::SimTime;

/// Mask of the 24-bit encoder count.
const ENC_COUNT_MASK: i64 = 0x00FF_FFFF;

/// A decoded address.
enum Target {
    Board(BoardRegister),
    /// 0-based axis.
    Axis(usize, AxisRegister),
    Hub(HubAddress),
    /// Another address space, with the address inside it (bits 11:0).
    Space(AddressSpace, u16),
    Unmapped,
}

fn decode(offset: u64) -> Target {
    let address = Address::from_offset(offset);
    if let Some(register) = address.register() {
        return match register {
            Register::Board(r) => Target::Board(r),
            Register::Axis { axis, register } => {
                Target::Axis(usize::from(axis).saturating_sub(1), register)
            }
        };
    }
    match address.space {
        AddressSpace::Main => Target::Unmapped,
        AddressSpace::Hub => address.hub().map_or(Target::Unmapped, Target::Hub),
        space => Target::Space(space, address.index),
    }
}

/// A read's target as the firmware decodes it: in the main space only
/// bits 7:0 (channel and register) count, so `0x0400` and
/// `0xFFFF_0000_0400` read STATUS (FPGA1394V2.v, QLA.v); at Rev 8 a space
/// the FPGA leaves unused (9-15) falls through to the QLA's register mux
/// and reads as the main space does (FPGA1394V2.v l.187-191: `0xC000`
/// reads STATUS). Writes decode the whole 16 bits ([`decode`]).
fn decode_read(offset: u64, rev8: bool) -> Target {
    let low = offset & 0xFFFF;
    let space = low >> 12;
    if space == 0 || (rev8 && space >= 9) {
        decode(low & 0xFF)
    } else {
        decode(low)
    }
}

/// The configuration ROM's bus-information block and root directory at
/// Rev 8, quadlet by quadlet from `0xFFFF_F000_0400` (FireWire.v l.351,
/// l.443-470): 12 quadlets, quadlet 4 the firmware version.
const CONFIG_ROM_REV8: [u32; 12] = [
    0x0404_8496,
    0x3133_3934,
    0x00FF_A000,
    0xFA61_0E0E,
    0x0000_0008,
    0x0005_9395,
    0x0C00_83C0,
    0x03FA_610E,
    0x8100_0003,
    0x1700_0002,
    0x8100_0006,
    0x0004_56C4,
];

/// Where the configuration ROM starts (a byte address, as the IEEE 1212
/// CSR space counts).
const CONFIG_ROM_BASE: u64 = 0xFFFF_F000_0400;

/// The upper half of the temperature quadlet in a real-time block: the
/// data collection buffer's status (Rev 8 QLA.v, DataBuffer.v): not
/// collecting (bit 15), channel 1 (bits 13:10), write address 0 (9:0).
/// Data collection is not modelled, so it stays at its power-up value.
pub(crate) const DATA_BUFFER_STATUS: u16 = 0x0400;

/// Space 7's status register (DataBuffer.v: `0x7800`).
const DATA_BUFFER_STATUS_INDEX: u16 = 0x800;

/// The velocity words of an encoder that has not moved since power-up
/// (Rev 8 EncPeriod.v l.74-82, l.162-164, l.188): every counter at its
/// largest value; the period overflowed, direction 1, partial; the quarter
/// cycles direction 1 without the overflow bit; the running counter
/// overflowed.
const PERIOD_BEFORE_ANY_EDGE: u32 = 0xCBFF_FFFF;
const QUARTER_BEFORE_ANY_EDGE: u32 = 0x43FF_FFFF;
const RUN_BEFORE_ANY_EDGE: u32 = 0x83FF_FFFF;

/// Volts per DAC count at the motor-supply comparator: the axis-4 DAC's
/// 2.5 V full scale over 16 bits, times the divider of 21
/// (`fpga-board-extras.md` §7: 24 V is about `0x7507`).
pub(crate) const COMPARATOR_VOLTS_PER_COUNT: f64 = 2.5 / 65535.0 * 21.0;

fn period_word(p: PeriodField) -> u32 {
    EncPeriod::default()
        .with_period(p.clocks)
        .with_overflow(p.overflow)
        .with_direction(p.up)
        .with_direction_changed(p.direction_changed)
        .with_error(p.error)
        .with_partial(p.partial)
        .raw()
}

fn quarter_word(q: QuarterField) -> u32 {
    EncQuarter::default()
        .with_period(q.clocks)
        .with_overflow(q.overflow)
        .with_direction(q.up)
        .with_edges(q.edge_mask)
        .raw()
}

fn run_word(r: RunField) -> u32 {
    EncRun::default()
        .with_clocks(r.clocks)
        .with_overflow(r.overflow)
        .raw()
}

/// The current-sense ADC code of a current (section 3: amps =
/// bits * 12.5 / 65536 - 6.25).
pub(crate) fn current_to_counts(amps: f64) -> u16 {
    round_to_code(current_to_codes(amps), 65535.0) as u16
}

/// [`current_to_counts`] before rounding, in ADC codes.
pub(crate) fn current_to_codes(amps: f64) -> f64 {
    (amps + QLA_FULL_SCALE_AMPS) / QLA_AMPS_PER_BIT
}

fn pot_to_counts(volts: f64) -> u16 {
    round_to_code(volts / POT_FULL_SCALE_VOLTS * 65535.0, 65535.0) as u16
}

/// What a QLA's MAX6576 sensor reads through the firmware: the sensor's
/// period is 10 us per kelvin, counted at 400 kHz (4 counts per degree)
/// from -273 degrees C; the firmware reports half the count, 0.5 degree C
/// per bit (the dVRK divides the byte by 2), truncated, and `0xFF` when the
/// count is out of its range (below 0 or from 128 degrees C on).
fn temperature_byte(celsius: f64) -> u8 {
    if !(0.0..128.0).contains(&celsius) {
        return 0xFF;
    }
    // Truncation: the counter holds whole quarter degrees and the
    // firmware drops its last bit; 127.5 up to 128 reads 0xFF in range.
    (celsius * 2.0) as u8
}

/// `x` rounded to the nearest whole code in `0..=max` (halves away from
/// zero; NaN reads 0; `max` a code, at most 65535): `round().clamp()`
/// without a call into libm (the x86-64 baseline has no rounding
/// instruction).
fn round_to_code(x: f64, max: f64) -> f64 {
    if x.is_nan() {
        return 0.0;
    }
    // Clamped first, the value is non-negative: truncating x + 1/2 rounds
    // it, halves up. Through i64, which holds every code exactly: one
    // instruction each way, where u64 takes a branchy sequence.
    ((x.clamp(0.0, max) + 0.5) as i64) as f64
}

impl Firmware {
    fn n_axes(&self) -> usize {
        self.axes.len()
    }

    /// Read one quadlet at `offset` (only its low 16 bits are decoded) at
    /// `now`, as a quadlet read request would. Unmapped addresses read 0.
    pub fn read_quadlet(&mut self, now: SimTime, offset: u64) -> u32 {
        self.advance(now);
        self.read_register(now, offset)
    }

    /// What a quadlet read of `offset` returns now (time caught up and the
    /// plant observed by the caller).
    fn read_register(&mut self, now: SimTime, offset: u64) -> u32 {
        let rev8 = self.cfg.profile.is_rev8();
        if rev8
            && let Some(k) = offset.checked_sub(CONFIG_ROM_BASE)
            && k % 4 == 0
            && let Some(&q) = CONFIG_ROM_REV8.get((k / 4) as usize)
        {
            // Quadlet 4 is the firmware version (9 on a Rev 9 board; the
            // header CRC word stays Rev 8's, not checked against Rev 9).
            return if k == 16 {
                self.cfg.firmware.number()
            } else {
                q
            };
        }
        match decode_read(offset, rev8) {
            Target::Board(r) => self.read_board_register(r),
            Target::Axis(i, r) => self.read_axis_register(i, r),
            Target::Hub(HubAddress::Memory(i)) => self.hub.read(usize::from(i), now),
            Target::Hub(HubAddress::Query) => self.hub.query_word(),
            Target::Hub(HubAddress::QuadletsWritten) => self.hub.num_written(),
            Target::Space(space, index) => self.read_space(space, index),
            Target::Hub(HubAddress::Unmapped(_)) | Target::Unmapped => 0,
        }
    }

    /// A quadlet of the PROM, Ethernet, 1-wire or waveform space.
    fn read_space(&self, space: AddressSpace, index: u16) -> u32 {
        let now = self.now;
        match space {
            AddressSpace::FpgaProm => self.fpga_prom.buffer_quadlet(index),
            AddressSpace::QlaProm => {
                let Some(prom) = self.qla_prom(index) else {
                    return 0;
                };
                match (index >> 8, index & 0xF) {
                    (0, 1) => u32::from(prom.status().raw() as u16),
                    (0, 2) => prom.result(),
                    (1, q) => prom.buffer_quadlet(usize::from(q)),
                    _ => 0,
                }
            }
            AddressSpace::Ethernet if self.cfg.fpga == FpgaVersion::V2 => {
                self.ethernet.window(index)
            }
            AddressSpace::Ethernet if self.cfg.fpga == FpgaVersion::V3 => {
                mdio_port_of(index).map_or(0, |port| self.ethernet_v3.mdio_read(port))
            }
            AddressSpace::OneWire => self.dallas.buffer_quadlet(index),
            AddressSpace::Waveform => self.dout.read_table(now, index),
            AddressSpace::FirewirePacket if self.cfg.profile.is_rev8() => {
                self.rx_memory.quadlet(index)
            }
            AddressSpace::DataCollection
                if self.cfg.profile.is_rev8() && index == DATA_BUFFER_STATUS_INDEX =>
            {
                u32::from(DATA_BUFFER_STATUS)
            }
            _ => 0,
        }
    }

    /// A write to the PROM, Ethernet, 1-wire or waveform space.
    fn write_space(&mut self, space: AddressSpace, index: u16, value: u32) {
        let now = self.now;
        match space {
            AddressSpace::FpgaProm => self.fpga_prom.stream(now, index, &[value]),
            AddressSpace::QlaProm => {
                let Some(prom) = self.qla_prom_mut(index) else {
                    return;
                };
                match (index >> 8, index & 0xF) {
                    (0, 0) => prom.command(now, QlaPromCommand(value)),
                    (1, q) => prom.set_buffer_quadlet(usize::from(q), value),
                    _ => {}
                }
            }
            AddressSpace::Waveform => self.dout.write_table(now, index, value),
            AddressSpace::Ethernet if self.cfg.fpga == FpgaVersion::V3 => {
                if let Some(port) = mdio_port_of(index) {
                    self.ethernet_v3.mdio_write(now, port, value);
                }
            }
            _ => {}
        }
    }

    /// Which QLA PROM a space-3 address (bits 7:4 the channel) reaches: a
    /// QLA1 uses channel 0, a DQLA channels 1 and 2.
    fn qla_prom_slot(&self, index: u16) -> Option<usize> {
        let channel = usize::from((index >> 4) & 0xF);
        if self.qla_proms.len() == 1 {
            (channel == 0).then_some(0)
        } else {
            channel.checked_sub(1)
        }
    }

    fn qla_prom(&self, index: u16) -> Option<&super::prom::QlaProm> {
        self.qla_prom_slot(index)
            .and_then(|i| self.qla_proms.get(i))
    }

    fn qla_prom_mut(&mut self, index: u16) -> Option<&mut super::prom::QlaProm> {
        self.qla_prom_slot(index)
            .and_then(|i| self.qla_proms.get_mut(i))
    }

    /// The motor-supply comparator of a QLA1 (DIGIN bit 28), or of a
    /// DQLA's first QLA: see [`supply_comparator_of`](Self::supply_comparator_of).
    pub(crate) fn supply_comparator(&self) -> bool {
        self.supply_comparator_of(0)
    }

    /// The motor-supply comparator of QLA `qla` (0, or 1 for a DQLA's
    /// second): its last DAC's voltage (axis 4, or axis 8) is below its
    /// motor supply, which is present only while it is good.
    pub(crate) fn supply_comparator_of(&self, qla: usize) -> bool {
        let command = self.axes.get(3 + 4 * qla).map_or(0, |a| a.command);
        let volts = if qla == 0 {
            self.cfg.motor_supply_volts
        } else {
            self.cfg.qla2_supply_volts
        };
        self.power.supply_good(self.now) && f64::from(command) * COMPARATOR_VOLTS_PER_COUNT < volts
    }

    /// Read `quadlets` quadlets from `offset` at `now`, as a block read
    /// would: a block read of the main space is a real-time block read
    /// (and restarts its timestamp), hub memory reads in arrival order,
    /// other addresses read register by register.
    pub fn read_block(&mut self, now: SimTime, offset: u64, quadlets: usize) -> Vec<u32> {
        let mut out = vec![0u8; quadlets * 4];
        self.read_block_into(now, offset, &mut out);
        field::quadlets(&out).collect()
    }

    /// [`read_block`](Self::read_block) into `out` (whole quadlets, wire
    /// order; its length says how many).
    pub(crate) fn read_block_into(&mut self, now: SimTime, offset: u64, out: &mut [u8]) {
        self.catch_up(now);
        let addr = (offset & 0xFFFF) as u16;
        if Address::from_offset(u64::from(addr)).space == AddressSpace::Main {
            // Any block read of the main space samples the real-time block
            // and answers from it, starting at the quadlet the offset names
            // (FireWire.v l.1306, l.1407); quadlets past the block read 0.
            let len = self.layout.read_block_len();
            let start = usize::from(addr) * 4;
            if start == 0
                && let Some((block, rest)) = out.split_at_mut_checked(len)
            {
                self.sample_block_into(now, block);
                rest.fill(0);
            } else {
                let mut block = vec![0u8; len];
                self.sample_block_into(now, &mut block);
                let from = block.get(start..).unwrap_or_default();
                let n = from.len().min(out.len());
                if let (Some(dst), Some(src)) = (out.get_mut(..n), from.get(..n)) {
                    dst.copy_from_slice(src);
                }
                if let Some(rest) = out.get_mut(n..) {
                    rest.fill(0);
                }
            }
            return;
        }
        if let Target::Hub(HubAddress::Memory(start)) = decode(u64::from(addr)) {
            // Hub memory reads straight from the memory (the timing
            // quadlet latched as it goes out); past its end, register by
            // register as the address space goes on.
            let start = usize::from(start);
            let in_hub = self.hub.read_into(start, now, out);
            for (k, q) in out.chunks_exact_mut(4).enumerate().skip(in_hub) {
                let v = self.read_register(now, u64::from(addr.wrapping_add(k as u16)));
                q.copy_from_slice(&v.to_be_bytes());
            }
            return;
        }
        self.observe();
        for (k, q) in out.chunks_exact_mut(4).enumerate() {
            let v = self.read_register(now, u64::from(addr.wrapping_add(k as u16)));
            q.copy_from_slice(&v.to_be_bytes());
        }
    }

    /// Write one quadlet at `offset` at `now`, as a quadlet write request
    /// addressed to this board would (refreshes the watchdog).
    pub fn write_quadlet(
        &mut self,
        now: SimTime,
        offset: u64,
        value: u32,
        phy: &mut dyn PhyAccess,
    ) {
        self.catch_up(now);
        self.watchdog.last_write = now;
        match decode(offset) {
            Target::Board(r) => self.write_board_register(now, r, value, phy),
            Target::Axis(i, r) => self.write_axis_register(now, i, r, value),
            Target::Hub(HubAddress::Query) => {
                self.query(now, Some(value));
                return;
            }
            Target::Space(space, index) => self.write_space(space, index, value),
            Target::Hub(_) | Target::Unmapped => return,
        }
        self.control_changed();
        self.sync_plant();
    }

    /// Write a block at `offset` at `now` (wire-order bytes, whole
    /// quadlets), as a block write addressed to this board would:
    /// address 0 takes a real-time write block (or this board's slice of
    /// a command block), hub memory takes a status broadcast, other
    /// addresses are written register by register.
    pub fn write_block(&mut self, now: SimTime, offset: u64, data: &[u8], phy: &mut dyn PhyAccess) {
        self.catch_up(now);
        self.write_block_from(now, offset, data, true, phy);
        self.sync_plant();
    }

    /// Block write; `unicast` when addressed to this node alone.
    #[inline]
    pub(crate) fn write_block_from(
        &mut self,
        now: SimTime,
        offset: u64,
        data: &[u8],
        unicast: bool,
        phy: &mut dyn PhyAccess,
    ) {
        self.watchdog.last_write = now;
        let addr = (offset & 0xFFFF) as u16;
        if u64::from(addr) == REALTIME_BLOCK_OFFSET {
            self.realtime_write(now, data, unicast);
            return;
        }
        match decode(u64::from(addr)) {
            Target::Hub(HubAddress::Memory(_)) => {
                if !self.hub.store(now, data, self.layout.format()) {
                    self.rx_error = Some(RxError::DuplicateBroadcast);
                }
            }
            Target::Hub(HubAddress::Query) => {
                if let Some(w) = field::quadlets(data).next() {
                    self.query(now, Some(w));
                }
            }
            // A page-program stream goes to the PROM whole.
            Target::Space(AddressSpace::FpgaProm, index) => {
                self.fpga_prom
                    .stream(now, index, &field::quadlets(data).collect::<Vec<_>>());
            }
            Target::Board(_) | Target::Axis(..) | Target::Space(..) => {
                self.control_changed();
                for (k, q) in field::quadlets(data).enumerate() {
                    match decode(u64::from(addr.wrapping_add(k as u16))) {
                        Target::Board(r) => self.write_board_register(now, r, q, phy),
                        Target::Axis(i, r) => self.write_axis_register(now, i, r, q),
                        Target::Space(space, index) => self.write_space(space, index, q),
                        _ => {}
                    }
                }
            }
            Target::Hub(_) | Target::Unmapped => {}
        }
    }

    /// A block write to address 0: a real-time write block, or a command
    /// block of concatenated write blocks from which this board takes the
    /// slice naming it (sections 5 and 6.5). A unicast Rev 4 or Rev 7 block of
    /// exactly one board's size is taken whatever board ID it carries.
    fn realtime_write(&mut self, now: SimTime, data: &[u8], unicast: bool) {
        let layout = self.layout;
        let own = unicast
            && layout.format() != BlockFormat::Rev8
            && data.len() == layout.write_block_len();
        let block = if own {
            WriteBlock::new_checked(data, layout).ok()
        } else {
            find_command_block(data, self.cfg.board_id, layout)
                .ok()
                .flatten()
        };
        let Some(block) = block else {
            return;
        };
        // The commands reach the plant. The next internal event moves only
        // when an amplifier request, the power or the watchdog flag
        // changes, which `request_amplifier` and `status_command` note
        // (most blocks change only the commands).
        self.drive_stale = true;
        for i in 0..self.n_axes() {
            if let Some(dac) = block.dac(i) {
                self.dac_write(now, i, dac);
            }
        }
        self.status_command(now, block.control().block_command());
    }

    fn read_board_register(&self, r: BoardRegister) -> u32 {
        match r {
            BoardRegister::Status => self.status_word().raw(),
            BoardRegister::PhyCtrl => self.phy_ctrl,
            BoardRegister::PhyData => self.phy_data.raw(),
            BoardRegister::Watchdog => WatchdogWord::default()
                .with_ticks(self.watchdog.ticks)
                .with_led_select(self.watchdog.led_select)
                .raw(),
            BoardRegister::HwVersion => u32::from(self.cfg.hardware.hardware_version()),
            BoardRegister::Temperature => self.temperature_word(),
            BoardRegister::DigitalOut => self.dout.read(self.now).raw(),
            BoardRegister::FwVersion => self.cfg.firmware.number(),
            BoardRegister::PromCmd => self.fpga_prom.status(self.now).raw(),
            BoardRegister::PromResult => self.fpga_prom.result(),
            BoardRegister::DigitalIn => self.digital_in().raw(),
            BoardRegister::IpAddr if self.cfg.fpga.has_ethernet() => self.ip_addr,
            BoardRegister::EthStatus if self.cfg.fpga == FpgaVersion::V2 => {
                self.ethernet.status().raw()
            }
            BoardRegister::EthStatus if self.cfg.fpga == FpgaVersion::V3 => self
                .ethernet_v3
                .status(self.now, self.cfg.profile.is_rev9())
                .raw(),
            BoardRegister::EthStatus => self.cfg.fpga.eth_status_bits(),
            BoardRegister::DallasStatus => self.dallas.status(self.now, true).raw(),
            BoardRegister::IoExpander => self.read_expander(),
            // GIT_DESC exists from Rev 9 on (BoardRegs.v); before, register
            // 15 reads 0.
            BoardRegister::GitDesc if self.cfg.firmware.number() >= 9 => self.cfg.git_desc,
            _ => 0,
        }
    }

    fn write_board_register(
        &mut self,
        now: SimTime,
        r: BoardRegister,
        value: u32,
        phy: &mut dyn PhyAccess,
    ) {
        match r {
            BoardRegister::Status => self.status_command(now, StatusWrite(value).command()),
            BoardRegister::PhyCtrl => {
                self.phy_ctrl = value;
                match PhyRequest::parse(value) {
                    Ok(PhyRequest::Read { register }) => {
                        let data = phy.read_phy_register(register);
                        self.phy_data = PhyData::default().with_register(register).with_data(data);
                    }
                    Ok(PhyRequest::Write { register, data }) => {
                        phy.write_phy_register(register, data);
                    }
                    Err(_) => {}
                }
            }
            BoardRegister::Watchdog => {
                let w = WatchdogWord(value);
                self.watchdog.ticks = w.ticks();
                // Rev 8 stores bit 31, the LED select (BoardRegs.v l.79).
                self.watchdog.led_select = self.cfg.profile.is_rev8() && w.led_select();
            }
            // Rev 8: PHY_DATA's 16 bits are host-writable (BoardRegs.v
            // l.94); a PHY read lands there too.
            BoardRegister::PhyData if self.cfg.profile.is_rev8() => {
                self.phy_data = PhyData(value & 0xFFFF);
            }
            BoardRegister::DigitalOut => self.dout.write(now, DigitalOutWrite::parse(value)),
            BoardRegister::PromCmd => self.fpga_prom.command(now, PromCommand(value)),
            BoardRegister::IpAddr if self.cfg.fpga.has_ethernet() => {
                self.ip_addr = stored_ip_address(self.cfg.profile, self.cfg.board_id, value);
            }
            BoardRegister::EthStatus if self.cfg.fpga == FpgaVersion::V2 => {
                self.ethernet.write(EthControl(value));
            }
            BoardRegister::EthStatus if self.cfg.fpga == FpgaVersion::V3 => {
                self.ethernet_v3.control(now, EthControlV3(value));
            }
            BoardRegister::DallasStatus => self.dallas.write(now, DallasControl(value)),
            BoardRegister::IoExpander => self.write_expander(ExpanderWrite(value)),
            _ => {}
        }
    }

    fn read_axis_register(&mut self, i: usize, r: AxisRegister) -> u32 {
        if r == AxisRegister::DoutCtrl {
            return self.dout.ctrl(i).map_or(0, DoutCtrl::raw);
        }
        if i >= self.n_axes() {
            return 0;
        }
        let rev8 = self.cfg.profile.is_rev8();
        let words = || self.velocity_words(i);
        match r {
            AxisRegister::Adc => self.adc_word(i, self.plant.noise_sample()).raw(),
            AxisRegister::Dac => self.axes.get(i).map_or(0, |a| u32::from(a.command)),
            AxisRegister::EncPreload => self.axes.get(i).map_or(0, |a| a.preload),
            AxisRegister::EncPosition => self.position_word(i).raw(),
            AxisRegister::EncPeriod => words().0.raw(),
            AxisRegister::EncQtr1 => words().1.raw(),
            AxisRegister::EncQtr5 => words().2.raw(),
            AxisRegister::EncRun => words().3.raw(),
            AxisRegister::MotorConfig if rev8 => self.motor_config_word(i).raw(),
            AxisRegister::MotorStatus if rev8 => self.motor_status_word(i).raw(),
            _ => 0,
        }
    }

    fn write_axis_register(&mut self, now: SimTime, i: usize, r: AxisRegister, value: u32) {
        if r == AxisRegister::DoutCtrl {
            if i < OUTPUTS {
                self.dout.write_ctrl(now, i, DoutCtrl(value));
            }
            return;
        }
        if i >= self.n_axes() {
            return;
        }
        let rev8 = self.cfg.profile.is_rev8();
        match r {
            AxisRegister::Dac => self.dac_write(now, i, DacWord(value)),
            AxisRegister::EncPreload => {
                self.observe();
                let raw = self.raw_count(i);
                if let Some(a) = self.axes.get_mut(i) {
                    a.preload = value & ENC_COUNT_MASK as u32;
                    a.count_offset = i64::from(a.preload) - raw;
                    a.overflow = false;
                }
            }
            // Bits 31 and 30 are stored; bits 25 and 24 say whether to
            // load the delay and the limit; the limit's bit 15 is always 0
            // (MotorChannelQLA.v l.196-199).
            AxisRegister::MotorConfig if rev8 => {
                let c = MotorConfig(value);
                if let Some(a) = self.axes.get_mut(i) {
                    a.disable_safety = c.disable_safety();
                    a.force_disable = c.force_disable();
                    if c.load_delay() {
                        a.enable_delay = c.enable_delay();
                    }
                    if c.load_limit() {
                        a.current_limit = c.current_limit() & 0x7FFF;
                    }
                }
            }
            _ => {}
        }
    }

    /// A DAC word (register or write block): command if valid, and on
    /// Rev 8 the amplifier request of bits 29:28. At Rev 8 the command
    /// and its control mode (bits 27:24) are taken only for a mode the
    /// board has: 0 (current), or 1 (voltage) with an I/O expander
    /// (MotorChannelQLA.v l.180-191).
    fn dac_write(&mut self, now: SimTime, i: usize, word: DacWord) {
        let rev8 = self.cfg.profile.is_rev8();
        let mode = word.control_mode();
        let mode_ok = !rev8 || mode == 0 || (mode == 1 && self.cfg.io_expander);
        if let Some(a) = self.axes.get_mut(i)
            && word.valid()
            && mode_ok
        {
            a.command = word.command();
            if rev8 {
                a.control_mode = mode;
            }
        }
        if rev8 && let Some(enable) = word.amp_request() {
            self.request_amplifier(now, i, enable);
        }
    }

    /// The host asks for amplifier `i` on or off. Asking for on clears the
    /// watchdog flag and the axis's safety disable; it takes effect only
    /// with motor power enabled. A change of the request or the flag marks
    /// the next internal event stale.
    fn request_amplifier(&mut self, now: SimTime, i: usize, enable: bool) {
        if enable && self.watchdog.timed_out {
            self.watchdog.timed_out = false;
            self.events_stale = true;
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
                self.events_stale = true;
            }
        } else if a.requested {
            a.requested = false;
            self.events_stale = true;
        }
    }

    /// A STATUS write (section 2): power, relay, amplifiers, reboot.
    /// Power is applied first, so one word may enable power and
    /// amplifiers. A change of what the next internal event depends on
    /// (the watchdog flag, the supply, an amplifier request) marks it
    /// stale.
    fn status_command(&mut self, now: SimTime, cmd: StatusCommand) {
        if cmd.reboot {
            self.reboot(now);
            return;
        }
        let before = (
            self.watchdog.timed_out,
            self.power.enabled,
            self.power.supply_on_since,
        );
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
                    if a.requested {
                        a.requested = false;
                        self.events_stale = true;
                    }
                }
            }
            None => {}
        }
        self.power.update_supply(now);
        let after = (
            self.watchdog.timed_out,
            self.power.enabled,
            self.power.supply_on_since,
        );
        if after != before {
            self.events_stale = true;
        }
        if let Some(relay) = cmd.relay {
            self.power.relay = relay;
        }
        for i in 0..4 {
            if let Some(enable) = cmd.amps.axis(i) {
                self.request_amplifier(now, i, enable);
            }
        }
    }

    /// Reboot (STATUS `0x00300000`): every register back to its power-up
    /// value; the plant keeps moving.
    fn reboot(&mut self, now: SimTime) {
        self.observe();
        self.control_changed();
        self.power = super::Power::new(self.power.supply_present, self.cfg.supply_rise);
        self.watchdog = Watchdog::new(now);
        self.axes = self
            .plant
            .axes()
            .iter()
            .map(|a| AxisState {
                edges_at_reset: a.encoder().edge_count(),
                ..AxisState::new(a.encoder().count())
            })
            .collect();
        self.phy_ctrl = 0;
        self.phy_data = PhyData::default();
        self.dout = super::DigitalOutputs::new();
        self.ip_addr = super::IP_UNASSIGNED;
        self.fpga_prom.reboot();
        for p in &mut self.qla_proms {
            p.reboot();
        }
        self.dallas.reboot();
        self.expanders = super::qla_expanders(&self.cfg.hardware);
        self.dqla_expanders = super::DqlaExpanders::new();
        self.expander_selected = 0;
        let link = self.ethernet.link();
        self.ethernet = super::Ethernet::new(self.cfg.board_id);
        self.ethernet.set_link(link);
        // The FPGA V3's Ethernet side (its PHYs, the PS Ethernet) is not
        // part of the reboot (FPGA1394V3.v: REBOOT reloads the PL only
        // through the PS, which the model does not restart).
        self.last_sample = now;
        self.hub = super::Hub::new(now, self.layout.format());
    }

    /// Register 14 as read: a QLA1's expander; on a DQLA the expander the
    /// last register-14 write named (DQLA.v's read mux; 0 when none).
    fn read_expander(&self) -> u32 {
        if self.cfg.hardware == Hardware::Qla1 {
            return self.expanders.first().map_or(0, |e| e.read());
        }
        let id = self.expander_selected;
        if let Some(chip) = DqlaExpanders::chip_of(id) {
            return self.dqla_expanders.read(chip);
        }
        // IDs 1 and 2: QLA 1's and QLA 2's MAX7317.
        match id {
            1 | 2 => self
                .expanders
                .get(usize::from(id - 1))
                .map_or(0, |e| e.read()),
            _ => 0,
        }
    }

    /// A register-14 write: every expander sees it and takes it if it
    /// names its ID.
    fn write_expander(&mut self, w: ExpanderWrite) {
        self.expander_selected = w.id();
        let inputs = [0, 1].map(|qla| ExpanderInputs {
            safety_feedback: self.power.relay,
            supply_comparator: self.supply_comparator_of(qla),
        });
        for (e, inputs) in self.expanders.iter_mut().zip(inputs) {
            e.write(w, inputs);
        }
        if self.cfg.hardware == Hardware::Dqla
            && let Some(chip) = DqlaExpanders::chip_of(w.id())
        {
            let lines = self.dqla_port_lines(chip);
            self.dqla_expanders.write(chip, w, lines);
        }
    }

    /// The lines QLA `qla`'s MAX7301 reads (DQLA.v's `IOP` mapping): 27
    /// supply good, 26:23 home 1-4, 22:19 negative limits, 18:17 positive
    /// limits 1-2, 16 power enable, 15:12 amplifier disables, 11:8 the
    /// amplifier lines (1 = amplifier on), 7:4 index.
    fn dqla_port_lines(&self, qla: usize) -> PortLines {
        let mut lines: PortLines = 0;
        let now = self.now;
        let expander = self.cfg.io_expander;
        if self.power.supply_good(now) {
            lines |= 1 << 27;
        }
        if self.power.enabled {
            lines |= 1 << 16;
        }
        let plugged = self.cfg.input_lines;
        for k in 0..4usize {
            let axis = 4 * qla + k;
            let (neg, pos, home) = self
                .plant
                .axis(axis)
                .map_or((false, false, false), |a| a.switches());
            let index = self.plant.axis(axis).is_some_and(|a| a.encoder().index());
            let on = self
                .axes
                .get(axis)
                .is_some_and(|a| a.is_on(&self.power, now, expander));
            // What is plugged in holds a QLA 1 line high (configured for
            // axes 1-4 only, as on a QLA1).
            let held = |group: usize| axis < 4 && (plugged >> (group + axis)) & 1 != 0;
            // Port numbers count axis 1 from the high end of each group.
            let bit = |top: u32, set: bool| if set { 1u32 << (top - k as u32) } else { 0 };
            lines |= bit(26, home || held(0));
            lines |= bit(22, neg || held(8));
            if k < 2 {
                lines |= bit(18, pos || held(4));
            }
            lines |= bit(15, !on);
            lines |= bit(11, on);
            lines |= bit(7, index);
        }
        lines
    }

    /// STATUS of a DQLA (BoardRegs-DQLA.v). Both QLAs share the power
    /// enable and the relay; each has its own supply comparator.
    fn dqla_status_word(&self) -> DqlaStatus {
        let now = self.now;
        let good = self.power.supply_good(now);
        let both = |on: bool| if on { 0b11 } else { 0 };
        let comparators =
            u8::from(self.supply_comparator_of(0)) | u8::from(self.supply_comparator_of(1)) << 1;
        DqlaStatus::default()
            .with_axes(self.n_axes() as u8)
            .with_board_id(self.cfg.board_id)
            .with_watchdog_timeout(self.watchdog.timed_out)
            .with_quad_dac(0b11)
            .with_motor_supply_good(good)
            .with_motor_power_enabled(self.power.enabled)
            .with_relay_on(self.power.relay)
            .with_supply_good_each(both(good))
            .with_dqla_expanders_ok(0b11)
            .with_dout_checked(0b11)
            .with_dout_bidirectional(0b11)
            .with_safety_feedback(both(self.power.relay))
            .with_supply_comparators(comparators)
            .with_waveform_active(self.dout.table_active(now))
            .with_io_expanders(both(self.cfg.io_expander))
    }

    /// DIGIN of a DQLA (BoardRegs-DQLA.v): the raw outputs and eight of
    /// each switch input.
    fn dqla_digital_in(&self) -> DqlaDigitalIn {
        let (mut neg, mut pos, mut home) = (0u8, 0u8, 0u8);
        for (i, axis) in self.plant.axes().iter().take(8).enumerate() {
            let (n, p, h) = axis.switches();
            neg |= u8::from(n) << i;
            pos |= u8::from(p) << i;
            home |= u8::from(h) << i;
        }
        let plugged = self.cfg.input_lines;
        DqlaDigitalIn::default()
            .with_outputs(self.dout.raw_outputs(self.now))
            .with_neg_limits(neg | ((plugged >> 8) & 0xF) as u8)
            .with_pos_limits(pos | ((plugged >> 4) & 0xF) as u8)
            .with_home(home | (plugged & 0xF) as u8)
    }

    fn raw_count(&self, i: usize) -> i64 {
        self.plant.axis(i).map_or(0, |a| a.encoder().count())
    }

    /// The velocity fields of axis `i` with the system clock counter at
    /// `now_clk`.
    fn velocity(&self, i: usize, now_clk: u64) -> VelocityFields {
        self.plant
            .axis(i)
            .map(|a| a.encoder().fields_at_clock(now_clk))
            .unwrap_or_default()
    }

    /// ENC_PERIOD, ENC_QTR1, ENC_QTR5 and ENC_RUN of axis `i` now. At Rev 8
    /// an encoder without an edge since power-up (or reboot) reads the
    /// firmware's power-up words.
    fn velocity_words(&self, i: usize) -> (EncPeriod, EncQuarter, EncQuarter, EncRun) {
        self.velocity_words_at(i, self.now.clocks())
    }

    /// [`velocity_words`](Self::velocity_words) with the system clock
    /// counter now, `now_clk`.
    fn velocity_words_at(
        &self,
        i: usize,
        now_clk: u64,
    ) -> (EncPeriod, EncQuarter, EncQuarter, EncRun) {
        let still = self.cfg.profile.is_rev8()
            && self
                .plant
                .axis(i)
                .zip(self.axes.get(i))
                .is_some_and(|(p, a)| p.encoder().edge_count() == a.edges_at_reset);
        if still {
            return (
                EncPeriod(PERIOD_BEFORE_ANY_EDGE),
                EncQuarter(QUARTER_BEFORE_ANY_EDGE),
                EncQuarter(QUARTER_BEFORE_ANY_EDGE),
                EncRun(RUN_BEFORE_ANY_EDGE),
            );
        }
        let f = self.velocity(i, now_clk);
        (
            EncPeriod(period_word(f.period)),
            EncQuarter(quarter_word(f.qtr1)),
            EncQuarter(quarter_word(f.qtr5)),
            EncRun(run_word(f.run)),
        )
    }

    fn status_word(&self) -> StatusRead {
        if self.cfg.hardware == Hardware::Dqla {
            return StatusRead(self.dqla_status_word().raw());
        }
        let now = self.now;
        let mut amp_enabled = 0u8;
        let mut amp_on = 0u8;
        let mut safety = 0u8;
        let expander = self.cfg.io_expander;
        for (i, a) in self.axes.iter().take(4).enumerate() {
            amp_enabled |= u8::from(a.requested) << i;
            amp_on |= u8::from(a.is_on(&self.power, now, expander)) << i;
            safety |= u8::from(a.safety_disabled) << i;
        }
        StatusRead::default()
            .with_axes(self.n_axes() as u8)
            .with_board_id(self.cfg.board_id)
            .with_watchdog_timeout(self.watchdog.timed_out)
            .with_quad_dac(true)
            .with_dout_checked(true)
            .with_dout_bidirectional(true)
            .with_motor_supply_good(self.power.supply_good(now))
            .with_motor_power_enabled(self.power.enabled)
            .with_relay_state(self.power.relay)
            .with_relay_on(self.power.relay)
            .with_motor_supply_fault(self.power.supply_fault())
            .with_safety_feedback(self.power.relay)
            .with_io_expander(self.cfg.io_expander)
            .with_amp_fault(if self.cfg.profile.is_rev8() {
                0
            } else {
                amp_on
            })
            .with_safety_amp_disable(safety)
            .with_amp_enabled(amp_enabled)
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
        let word = |a: usize, b: usize| {
            Temperature::default()
                .with_upper(pair(a))
                .with_lower(pair(b))
                .raw()
        };
        // A DQLA reports its second QLA's sensors in bits 31:16.
        if self.n_axes() > 4 {
            word(0, 1) | (word(2, 3) << 16)
        } else {
            word(0, 1)
        }
    }

    fn digital_in(&self) -> DigitalIn {
        if self.cfg.hardware == Hardware::Dqla {
            return DigitalIn(self.dqla_digital_in().raw());
        }
        let (mut a, mut b, mut index) = (0u8, 0u8, 0u8);
        let (mut neg, mut pos, mut home) = (0u8, 0u8, 0u8);
        for (i, axis) in self.plant.axes().iter().take(4).enumerate() {
            let enc = axis.encoder();
            let (n, p, h) = axis.switches();
            a |= u8::from(enc.a()) << i;
            b |= u8::from(enc.b()) << i;
            index |= u8::from(enc.index()) << i;
            neg |= u8::from(n) << i;
            pos |= u8::from(p) << i;
            home |= u8::from(h) << i;
        }
        // What is plugged in holds some switch inputs high.
        let plugged = self.cfg.input_lines;
        let neg = neg | ((plugged >> 8) & 0xF) as u8;
        let pos = pos | ((plugged >> 4) & 0xF) as u8;
        let home = home | (plugged & 0xF) as u8;
        DigitalIn::default()
            .with_v_fault(self.power.supply_fault())
            .with_waveform_active(self.dout.table_active(self.now))
            .with_supply_comparator(self.supply_comparator())
            .with_enc_a(a)
            .with_enc_b(b)
            .with_index(index)
            .with_outputs(self.dout.raw_outputs(self.now))
            .with_neg_limits(neg)
            .with_pos_limits(pos)
            .with_home(home)
    }

    /// The ADC quadlet of axis `i`, the noise drawn at sample `sample`
    /// (the plant's [`noise_sample`](crate::plant::Plant::noise_sample)
    /// now).
    #[inline(always)]
    fn adc_word(&self, i: usize, sample: u64) -> AdcWord {
        AdcWord::default()
            .with_pot(pot_to_counts(self.plant.measured_pot_at_sample(i, sample)))
            .with_current(current_to_counts(
                self.plant.measured_current_at_sample(i, sample),
            ))
    }

    fn position_word(&mut self, i: usize) -> EncPosition {
        let rev8 = self.cfg.profile.is_rev8();
        // The raw count, and at Rev 8 the index, B and A lines.
        let (raw, lines) = self.plant.axis(i).map_or((0, (false, false, false)), |a| {
            let e = a.encoder();
            let lines = if rev8 {
                (e.index(), e.b(), e.a())
            } else {
                (false, false, false)
            };
            (e.count(), lines)
        });
        let Some(a) = self.axes.get_mut(i) else {
            return EncPosition::default();
        };
        let count = raw + a.count_offset;
        if !(0..=ENC_COUNT_MASK).contains(&count) {
            a.overflow = true;
        }
        let word = EncPosition::default()
            .with_counts_wrapping(count - i64::from(ENC_NEUTRAL))
            .with_overflow(a.overflow);
        if rev8 {
            word.with_index(lines.0).with_b(lines.1).with_a(lines.2)
        } else {
            word
        }
    }

    /// MOTOR_CONFIG (MotorChannelQLA.v l.79): bits 31 and 30 as written,
    /// 25 voltage control available (an I/O expander), 24 current control
    /// (always), the delay and the limit.
    fn motor_config_word(&self, i: usize) -> MotorConfig {
        let a = self.axes.get(i);
        MotorConfig::default()
            .with_disable_safety(a.is_some_and(|a| a.disable_safety))
            .with_force_disable(a.is_some_and(|a| a.force_disable))
            .with_voltage_mode(self.cfg.io_expander)
            .with_current_mode(true)
            .with_enable_delay(a.map_or(0, |a| a.enable_delay))
            .with_current_limit(a.map_or(0, |a| a.current_limit))
    }

    fn motor_status_word(&self, i: usize) -> MotorStatus {
        let Some(a) = self.axes.get(i) else {
            return MotorStatus::default();
        };
        // Bits 27:24 the control mode, 20 current control (MotorChannelQLA.v
        // l.172).
        let expander = self.cfg.io_expander;
        MotorStatus::default()
            .with_amp_on(a.is_on(&self.power, self.now, expander))
            .with_amp_requested(a.requested)
            .with_control_mode(a.control_mode)
            .with_current_control(a.current_control(expander))
            .with_safety_disable(a.safety_disabled)
            .with_amp_fault(false)
            .with_current_command(a.command)
    }

    /// Sample the real-time read block at `now` (section 4), wire order,
    /// into `buf` (at least the layout's read block long; the rest is left
    /// alone), and restart the timestamp. Every byte of the block is
    /// written, whatever `buf` held (`a_sample_writes_every_quadlet`).
    pub(crate) fn sample_block_into(&mut self, now: SimTime, buf: &mut [u8]) {
        self.observe();
        let timestamp = now.clocks().wrapping_sub(self.last_sample.clocks()) as u32;
        self.last_sample = now;
        let layout = self.layout;
        let n = self.n_axes().min(layout.motors()).min(layout.encoders());
        let status = self.status_word();
        let digital_in = self.digital_in();
        let rev8 = self.cfg.profile.is_rev8();
        // At Rev 8 the block's temperature quadlet carries the data
        // buffer's status in bits 31:16 (QLA.v: `temp_sense` with
        // `reg_databuf` while `blk_rt_rd`); a DQLA keeps its second pair
        // of sensors there.
        let upper = if rev8 && self.n_axes() <= 4 {
            u32::from(DATA_BUFFER_STATUS) << 16
        } else {
            0
        };
        let temperature = Temperature(self.temperature_word() | upper);
        // The encoders' velocity fields are latched at this board's now.
        let now_clk = self.now.clocks();
        // The plant's clock stays while the sample is taken: one noise
        // sample index for every axis's pot and current.
        let noise_sample = self.plant.noise_sample();
        let Some(buf) = buf.get_mut(..layout.read_block_len()) else {
            return;
        };
        // Every quadlet is written below when the board has an axis for
        // every motor and encoder of the layout (fixed quadlets, ADC,
        // encoder sections, Rev 8 MOTOR_STATUS); otherwise the missing
        // axes' quadlets read 0.
        if n < layout.motors() || n < layout.encoders() {
            buf.fill(0);
        }
        let mut block = ReadBlock::new_unchecked(&mut buf[..], layout);
        block.set_timestamp(timestamp);
        block.set_status(status);
        block.set_digital_in(digital_in);
        block.set_temperature(temperature);
        for i in 0..n {
            let position = self.position_word(i);
            let (period, qtr1, qtr5, run) = self.velocity_words_at(i, now_clk);
            let motor = MotorReading {
                adc: self.adc_word(i, noise_sample),
                status: if rev8 {
                    self.motor_status_word(i)
                } else {
                    MotorStatus::default()
                },
            };
            let encoder = EncoderReading {
                position,
                period,
                qtr1,
                qtr5,
                run,
            };
            write_axis(buf, layout, i, motor, encoder);
        }
    }
}

/// Axis `axis`'s quadlets of a real-time read block of `layout` in `buf`,
/// written as [`ReadBlock::set_axis`] writes them (the test
/// `write_axis_matches_set_axis` holds the two together), without its
/// bounds error and call: the ADC quadlet after the four fixed ones, the
/// encoder sections (position only at Rev 4; position, period, QTR1,
/// QTR5, run later) after the ADC quadlets, at Rev 8 MOTOR_STATUS after
/// them. An axis beyond the layout's motors or encoders writes nothing;
/// quadlets beyond `buf` are not written.
#[inline(always)]
fn write_axis(
    buf: &mut [u8],
    layout: BoardLayout,
    axis: usize,
    motor: MotorReading,
    encoder: EncoderReading,
) {
    /// Timestamp, STATUS, DIGITAL_IN and TEMPERATURE.
    const FIXED_QUADLETS: usize = 4;
    let (m, e) = (layout.motors(), layout.encoders());
    if axis >= m || axis >= e {
        return;
    }
    let sections = match layout.format() {
        BlockFormat::Rev4 => 1,
        BlockFormat::Rev7 | BlockFormat::Rev8 => 5,
    };
    let encoder_start = FIXED_QUADLETS + m;
    field::write_quadlet(buf, FIXED_QUADLETS + axis, motor.adc.0);
    let words = [
        encoder.position.0,
        encoder.period.0,
        encoder.qtr1.0,
        encoder.qtr5.0,
        encoder.run.0,
    ];
    for (k, word) in words.into_iter().enumerate().take(sections) {
        field::write_quadlet(buf, encoder_start + k * e + axis, word);
    }
    if layout.format() == BlockFormat::Rev8 {
        field::write_quadlet(buf, encoder_start + sections * e + axis, motor.status.0);
    }
}

#[cfg(test)]
mod tests {
    use super::{round_to_code, temperature_byte};
    use crate::qla::config::{BoardConfig, Hardware, Profile};
    use crate::qla::{Firmware, PhyRegisters};
    use crate::time::{SimDuration, SimTime};
    use firelink_wire::qla::realtime::WriteBlockRepr;
    use firelink_wire::qla::registers::{DAC_ZERO, DacWord, StatusCommand};

    /// A sample writes every quadlet of the read block (its memory is not
    /// cleared first when every axis is sampled): into memory that held
    /// garbage it is the same as into cleared memory, on every profile and
    /// both boards, at power-up and with motor power, amplifiers and
    /// moving axes.
    #[test]
    fn a_sample_writes_every_quadlet() {
        for profile in [Profile::Seed, Profile::Rev7, Profile::Rev8, Profile::Rev9] {
            for hardware in [Hardware::Qla1, Hardware::Dqla] {
                let cfg = BoardConfig::new(2, hardware, profile);
                let len = cfg.layout().read_block_len();
                let mut fw = Firmware::new(cfg);
                let mut phy = PhyRegisters::new(2);
                for k in 1u64..=6 {
                    let now = SimTime::from_micros(500 * k);
                    if k == 2 {
                        let on = StatusCommand {
                            power: Some(true),
                            relay: Some(true),
                            ..StatusCommand::NONE
                        };
                        fw.write_quadlet(now, 0, on.to_word().raw(), &mut phy);
                    }
                    if k == 3 {
                        let amps = StatusCommand::amplifiers(0xFF, 0xFF).to_word().raw();
                        fw.write_quadlet(now, 0, amps, &mut phy);
                        for axis in 0..hardware.axes() {
                            if let Some(a) = fw.plant_mut().axis_mut(axis) {
                                a.set_external_torque(0.2 * (axis as f64 + 1.0));
                            }
                        }
                    }
                    let mut cleared = fw.clone();
                    let mut garbage = vec![0xA5; len];
                    let mut zeros = vec![0; len];
                    fw.sample_block_into(now, &mut garbage);
                    cleared.sample_block_into(now, &mut zeros);
                    assert_eq!(garbage, zeros, "{profile:?} {hardware:?} at {k}");
                }
            }
        }
    }

    /// The axis quadlets written directly are `ReadBlock::set_axis`'s, for
    /// every layout (QLA1 and DQLA; Rev 4, 7, 8, 9), every axis and one
    /// beyond, into buffers longer and shorter than the block.
    #[test]
    fn write_axis_matches_set_axis() {
        use firelink_wire::qla::realtime::{
            BoardLayout, EncoderReading, FirmwareRev, MotorReading, ReadBlock,
        };
        use firelink_wire::qla::registers::{
            AdcWord, EncPeriod, EncPosition, EncQuarter, EncRun, MotorStatus,
        };
        let revs = [
            FirmwareRev::Rev4,
            FirmwareRev::Rev7,
            FirmwareRev::Rev8,
            FirmwareRev::Rev9,
        ];
        let mut compared = 0;
        for rev in revs {
            for layout in [BoardLayout::qla1(rev), BoardLayout::dqla(rev)] {
                let len = layout.read_block_len();
                // Longer than the block (nothing written past it), exact,
                // short (nothing written past the buffer).
                for size in [len + 12, len, len - 4, len - 9] {
                    for axis in 0..=layout.motors().max(layout.encoders()) {
                        let k = axis as u32 * 0x0101_0101;
                        let motor = MotorReading {
                            adc: AdcWord(0x1111_1111 ^ k),
                            status: MotorStatus(0x2222_2222 ^ k),
                        };
                        let encoder = EncoderReading {
                            position: EncPosition(0x3333_3333 ^ k),
                            period: EncPeriod(0x4444_4444 ^ k),
                            qtr1: EncQuarter(0x5555_5555 ^ k),
                            qtr5: EncQuarter(0x6666_6666 ^ k),
                            run: EncRun(0x7777_7777 ^ k),
                        };
                        let mut expected = vec![0xA5; size];
                        let mut block = ReadBlock::new_unchecked(&mut expected[..], layout);
                        let _ = block.set_axis(axis, motor, encoder);
                        let mut written = vec![0xA5; size];
                        super::write_axis(&mut written, layout, axis, motor, encoder);
                        assert_eq!(
                            written, expected,
                            "{rev:?} {layout:?} axis {axis}, {size} bytes"
                        );
                        compared += usize::from(written.iter().any(|b| *b != 0xA5));
                    }
                }
            }
        }
        assert!(compared > 50, "{compared}");
    }

    /// A real-time block that changes only the commands leaves the next
    /// internal event as it was worked out; one that changes the power,
    /// an amplifier request or the watchdog flag marks it stale; an event
    /// works out the next. Either way the board goes through exactly the
    /// states of a board that works the next event out afresh every 10 us
    /// of virtual time (so that none can be missed): power on, amplifiers
    /// requested (per STATUS, and at Rev 8 per DAC word too), their enable
    /// delays, the current check, and three watchdog timeouts, the second
    /// and third after a block that cleared the flag with nothing else
    /// scheduled (power on again; an amplifier request).
    #[test]
    fn command_only_blocks_keep_the_next_event_and_change_nothing() {
        for profile in [Profile::Rev7, Profile::Rev8] {
            let cfg = BoardConfig::new(3, Hardware::Qla1, profile);
            let layout = cfg.layout();
            let mut fw = Firmware::new(cfg);
            let mut reference = fw.clone();
            let mut phy = PhyRegisters::new(3);
            let (mut kept, mut seen_on, mut timeouts) = (0, false, 0);
            for k in 1u16..=920 {
                let now = SimTime::from_micros(200 * u64::from(k));
                // Quiet for 34 to 36 ms at a time: the 30 ms watchdog fires.
                let quiet = [300..470, 521..700, 721..900]
                    .iter()
                    .any(|r| r.contains(&k));
                if !quiet {
                    let mut block = WriteBlockRepr::new(layout, 3);
                    for (i, dac) in block.dac.iter_mut().enumerate() {
                        let code = DAC_ZERO + (k * 37 + i as u16 * 11) % 300;
                        let mut word = DacWord::valid_command(code);
                        if profile == Profile::Rev8 && k == 701 && i == 1 {
                            word = word.with_amp_request(Some(true));
                        }
                        *dac = word;
                    }
                    let command = match k {
                        1 => StatusCommand {
                            power: Some(true),
                            relay: Some(true),
                            ..StatusCommand::NONE
                        },
                        5 => StatusCommand::amplifiers(0b1101, 0b1101),
                        200 => StatusCommand::amplifiers(0b0100, 0),
                        480 => StatusCommand::power(true),
                        701 => StatusCommand::amplifiers(0b0001, 0b0001),
                        910 => StatusCommand::power(false),
                        _ => StatusCommand::NONE,
                    };
                    block.control = command.to_word();
                    let mut bytes = vec![0; block.buffer_len()];
                    block.emit(&mut bytes).unwrap();
                    fw.write_block(now, 0, &bytes, &mut phy);
                    reference.write_block(now, 0, &bytes, &mut phy);
                    kept += usize::from(!fw.events_stale);
                }
                let was_timed_out = fw.watchdog_timed_out();
                fw.pass_time(now + SimDuration::from_micros(50));
                fw.advance(now + SimDuration::from_micros(90));
                for micros in (0..=90).step_by(10) {
                    reference.events_stale = true;
                    reference.pass_time(now + SimDuration::from_micros(micros));
                }
                reference.advance(now + SimDuration::from_micros(90));
                assert_eq!(
                    fw.state_digest(),
                    reference.state_digest(),
                    "{profile:?}, step {k}"
                );
                seen_on |= fw.amplifier_on(0);
                timeouts += usize::from(!was_timed_out && fw.watchdog_timed_out());
            }
            assert!(seen_on, "{profile:?}: an amplifier came on");
            assert_eq!(timeouts, 3, "{profile:?}: every quiet stretch timed out");
            // 392 blocks, of which six change more than the commands.
            assert!(kept >= 380, "{profile:?}: {kept} blocks kept the event");
            assert!(!fw.amplifier_on(0), "{profile:?}: power went off");
        }
    }

    /// The MAX6576 byte as the dVRK reads it (sawRobotIO1394: the byte
    /// divided by 2 is degrees C).
    #[test]
    fn temperatures_read_half_a_degree_per_bit() {
        let dvrk = |c: f64| f64::from(temperature_byte(c)) / 2.0;
        assert_eq!(temperature_byte(25.0), 50);
        assert_eq!(dvrk(25.0), 25.0);
        assert_eq!(dvrk(31.74), 31.5, "truncated to the half degree");
        assert_eq!(temperature_byte(0.0), 0);
        assert_eq!(temperature_byte(127.4), 254);
        // Outside the counter's range: 0xFF.
        for c in [-0.1, -40.0, 128.0, 200.0, f64::NAN, f64::INFINITY] {
            assert_eq!(temperature_byte(c), 0xFF, "{c}");
        }
    }

    #[test]
    fn codes_round_as_round_then_clamp() {
        for x in [
            -1e300, -3.5, -0.5, -0.49, 0.0, 0.49, 0.5, 1.5, 2.5, 254.4, 254.5, 255.5, 1e300,
            65534.5, 65535.2, 12345.678,
        ] {
            for max in [255.0, 65535.0] {
                assert_eq!(
                    round_to_code(x, max),
                    x.round().clamp(0.0, max),
                    "{x} {max}"
                );
            }
        }
        assert_eq!(round_to_code(f64::NAN, 255.0), 0.0);
    }
}

/// What a write of `value` to REG_IPADDR (11) stores: Rev 9 adds the board
/// ID to the address's last byte, bits 31:24 as the host writes it
/// (EthernetIO.v `desired_ip_address`: 169.254.0.100 becomes
/// 169.254.0.{100 + ID}), except to the unassigned `0xFFFFFFFF`; earlier
/// firmware stores the value as written.
pub(crate) fn stored_ip_address(profile: Profile, board_id: u8, value: u32) -> u32 {
    if profile != Profile::Rev9 || value == super::IP_UNASSIGNED {
        return value;
    }
    let last = ((value >> 24) as u8).wrapping_add(board_id & 0xF);
    (value & 0x00FF_FFFF) | (u32::from(last) << 24)
}

#[cfg(test)]
mod ip_address_tests {
    use super::*;

    #[test]
    fn rev9_adds_the_board_id_to_the_last_byte() {
        // 169.254.0.100 as the host writes it (first byte lowest).
        let base = u32::from_le_bytes([169, 254, 0, 100]);
        let stored = stored_ip_address(Profile::Rev9, 5, base);
        assert_eq!(stored.to_le_bytes(), [169, 254, 0, 105]);
        assert_eq!(stored_ip_address(Profile::Rev8, 5, base), base);
        assert_eq!(
            stored_ip_address(Profile::Rev9, 5, super::super::IP_UNASSIGNED),
            0xFFFF_FFFF
        );
        // The 8-bit sum wraps as the firmware's does.
        let high = u32::from_le_bytes([10, 0, 0, 250]);
        assert_eq!(
            stored_ip_address(Profile::Rev9, 15, high).to_le_bytes(),
            [10, 0, 0, 9]
        );
    }
}
