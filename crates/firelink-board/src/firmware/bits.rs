//! Register quadlet packing, bit by bit from `fpga-board.md` sections 2-6.
//!
//! Interim: these small helpers stand in for the `firelink_wire::board`
//! codecs until they are merged; every bit position the firmware uses is
//! here and nowhere else, so the switch touches this file only.

use crate::plant::encoder::{PeriodField, QuarterField, RunField};

/// STATUS as read (section 2, "STATUS read").
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct StatusBits {
    pub axes: u8,
    pub board_id: u8,
    pub watchdog_timeout: bool,
    pub quad_dac: bool,
    pub supply_good: bool,
    pub power_enabled: bool,
    pub relay_state: bool,
    pub relay_on: bool,
    pub supply_fault: bool,
    pub safety_feedback: bool,
    pub io_expander: bool,
    /// Bits 11:8 (Rev < 8).
    pub amp_status: u8,
    pub safety_amp_disable: u8,
    pub amp_enabled: u8,
}

pub(crate) fn status_read(s: StatusBits) -> u32 {
    (u32::from(s.axes & 0xF) << 28)
        | (u32::from(s.board_id & 0xF) << 24)
        | (u32::from(s.watchdog_timeout) << 23)
        | (u32::from(s.quad_dac) << 22)
        | (u32::from(s.supply_good) << 19)
        | (u32::from(s.power_enabled) << 18)
        | (u32::from(s.relay_state) << 17)
        | (u32::from(s.relay_on) << 16)
        | (u32::from(s.supply_fault) << 15)
        | (u32::from(s.safety_feedback) << 14)
        | (u32::from(s.io_expander) << 12)
        | (u32::from(s.amp_status & 0xF) << 8)
        | (u32::from(s.safety_amp_disable & 0xF) << 4)
        | u32::from(s.amp_enabled & 0xF)
}

/// The meaning of a STATUS write (section 2, "STATUS write").
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct StatusCommand {
    pub power: Option<bool>,
    pub relay: Option<bool>,
    /// Amplifiers to change (bit i = axis i).
    pub amp_mask: u8,
    /// Their new states.
    pub amp_enable: u8,
    pub reboot: bool,
}

pub(crate) fn status_write(word: u32) -> StatusCommand {
    let bit = |n: u32| word >> n & 1 == 1;
    let amp_mask = ((word >> 8) & 0xF) as u8;
    StatusCommand {
        power: bit(19).then_some(bit(18)),
        relay: bit(17).then_some(bit(16)),
        amp_mask,
        amp_enable: (word & 0xF) as u8 & amp_mask,
        reboot: (word >> 20) & 3 == 3,
    }
}

/// Bits of a real-time block's control quadlet that take effect (section 5).
pub(crate) const BLOCK_CONTROL_BITS: u32 = 0x000F_FFFF;

/// A PHY_CTRL write (section 2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum PhyRequest {
    Read(u8),
    Write(u8, u8),
}

pub(crate) fn phy_ctrl(word: u32) -> PhyRequest {
    if word & 0x1000 != 0 {
        PhyRequest::Write(((word >> 8) & 0xF) as u8, word as u8)
    } else {
        PhyRequest::Read((word & 0xF) as u8)
    }
}

pub(crate) fn phy_data(register: u8, data: u8) -> u32 {
    (u32::from(register & 0xF) << 8) | u32::from(data)
}

/// DIGITAL_OUT write: (mask, levels) of the 4 outputs.
pub(crate) fn digital_out(word: u32) -> (u8, u8) {
    let mask = ((word >> 8) & 0xF) as u8;
    let inverted = (word & 0xF) as u8;
    (mask, !inverted & mask)
}

/// DIGITAL_IN (section 2); each field 4 bits, bit i = axis i.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct DigitalInBits {
    pub v_fault: bool,
    pub enc_a: u8,
    pub enc_b: u8,
    pub index: u8,
    pub outputs: u8,
    pub neg_limits: u8,
    pub pos_limits: u8,
    pub home: u8,
}

pub(crate) fn digital_in(d: DigitalInBits) -> u32 {
    (u32::from(d.v_fault) << 31)
        | (u32::from(d.enc_a & 0xF) << 24)
        | (u32::from(d.enc_b & 0xF) << 20)
        | (u32::from(d.index & 0xF) << 16)
        | (u32::from(d.outputs & 0xF) << 12)
        | (u32::from(d.neg_limits & 0xF) << 8)
        | (u32::from(d.pos_limits & 0xF) << 4)
        | u32::from(d.home & 0xF)
}

pub(crate) fn temperature(upper: u8, lower: u8) -> u32 {
    (u32::from(upper) << 8) | u32::from(lower)
}

pub(crate) fn adc(pot: u16, current: u16) -> u32 {
    (u32::from(pot) << 16) | u32::from(current)
}

/// A DAC word (section 3) or a real-time write block motor quadlet
/// (section 5).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct DacWord {
    pub valid: bool,
    /// Rev 8: Some(enable) when bit 29 (mask) is set.
    pub amp_request: Option<bool>,
    /// Rev 7 write blocks: the board ID in bits 27:24.
    pub board_id: u8,
    pub command: u16,
}

pub(crate) fn dac(word: u32) -> DacWord {
    DacWord {
        valid: word >> 31 == 1,
        amp_request: (word >> 29 & 1 == 1).then_some(word >> 28 & 1 == 1),
        board_id: ((word >> 24) & 0xF) as u8,
        command: word as u16,
    }
}

pub(crate) const ENC_COUNT_MASK: u32 = 0x00FF_FFFF;

pub(crate) fn enc_position(count24: u32, overflow: bool, lines: Option<(bool, bool, bool)>) -> u32 {
    let mut w = (count24 & ENC_COUNT_MASK) | (u32::from(overflow) << 24);
    if let Some((index, b, a)) = lines {
        w |= (u32::from(index) << 30) | (u32::from(b) << 29) | (u32::from(a) << 28);
    }
    w
}

pub(crate) fn enc_period(p: PeriodField) -> u32 {
    (p.clocks & 0x03FF_FFFF)
        | (u32::from(p.overflow) << 31)
        | (u32::from(p.up) << 30)
        | (u32::from(p.direction_changed) << 29)
        | (u32::from(p.error) << 28)
        | (u32::from(p.partial) << 27)
}

pub(crate) fn enc_quarter(q: QuarterField) -> u32 {
    (q.clocks & 0x03FF_FFFF)
        | (u32::from(q.overflow) << 31)
        | (u32::from(q.up) << 30)
        | (u32::from(q.edge_mask & 0xF) << 26)
}

pub(crate) fn enc_run(r: RunField) -> u32 {
    (r.clocks & 0x03FF_FFFF) | (u32::from(r.overflow) << 31)
}

/// MOTOR_CONFIG (section 3): the writable part.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct MotorConfig {
    /// Amplifier enable delay in 20.83 us units (48 kHz).
    pub enable_delay: u8,
    /// Largest |command - 0x8000| in DAC counts.
    pub current_limit: u16,
}

pub(crate) fn motor_config_read(c: MotorConfig, voltage_mode: bool) -> u32 {
    (u32::from(voltage_mode) << 25)
        | (1 << 24)
        | (u32::from(c.enable_delay) << 16)
        | u32::from(c.current_limit)
}

pub(crate) fn motor_config_write(word: u32) -> MotorConfig {
    MotorConfig {
        enable_delay: (word >> 16) as u8,
        current_limit: word as u16,
    }
}

/// MOTOR_STATUS (section 3).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct MotorStatusBits {
    pub amp_on: bool,
    pub amp_requested: bool,
    pub safety_disable: bool,
    pub amp_fault: bool,
    pub command: u16,
}

pub(crate) fn motor_status(s: MotorStatusBits) -> u32 {
    (u32::from(s.amp_on) << 29)
        | (u32::from(s.amp_requested) << 28)
        | (u32::from(s.safety_disable) << 17)
        | (u32::from(s.amp_fault) << 16)
        | u32::from(s.command)
}

/// The query word (section 6.1): (sequence, board mask).
pub(crate) fn query(word: u32) -> (u16, u16) {
    ((word >> 16) as u16, word as u16)
}

pub(crate) fn query_word(seq: u16, mask: u16) -> u32 {
    (u32::from(seq) << 16) | u32::from(mask)
}

/// Header of a status broadcast (section 6.2): sequence and size in
/// quadlets (header included).
pub(crate) fn broadcast_header(seq: u16, quadlets: u16) -> u32 {
    (u32::from(seq) << 16) | u32::from(quadlets)
}

pub(crate) fn broadcast_header_parse(word: u32) -> (u16, u16) {
    ((word >> 16) as u16, word as u16)
}

/// Rev 8 hub header (section 6.3): `size:8 | seq_low:8 | seq_error:1 |
/// update_time:15`.
pub(crate) fn hub_header_rev8(size: u16, seq: u16, seq_error: bool, update_clocks: u64) -> u32 {
    (u32::from(size.min(0xFF)) << 24)
        | (u32::from(seq & 0xFF) << 16)
        | (u32::from(seq_error) << 15)
        | update_clocks.min(0x7FFF) as u32
}

/// Rev 7 hub header (section 6.3): `seq:16 | update_time:16`.
pub(crate) fn hub_header_rev7(seq: u16, update_clocks: u64) -> u32 {
    (u32::from(seq) << 16) | update_clocks.min(0xFFFF) as u32
}

/// The hub timing trailer (section 6.3): `read_start:16 | now:16`.
pub(crate) fn hub_trailer(read_start_clocks: u64, now_clocks: u64) -> u32 {
    ((read_start_clocks.min(0xFFFF) as u32) << 16) | now_clocks.min(0xFFFF) as u32
}

/// Rev 8 write block header (section 5): (board ID, quadlets).
pub(crate) fn write_header(word: u32) -> (u8, usize) {
    (((word >> 8) & 0xF) as u8, (word & 0xFF) as usize)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spec_examples() {
        // fpga-board.md section 2: power on/off, relay on/off words.
        assert_eq!(status_write(0x000C_0000).power, Some(true));
        assert_eq!(status_write(0x0008_0000).power, Some(false));
        assert_eq!(status_write(0x0003_0000).relay, Some(true));
        assert_eq!(status_write(0x0002_0000).relay, Some(false));
        assert!(status_write(0x0030_0000).reboot);
        let amps = status_write(0x0000_0305);
        assert_eq!((amps.amp_mask, amps.amp_enable), (3, 1));
        assert_eq!(phy_ctrl(0x1000 | 1 << 8 | 0x3F), PhyRequest::Write(1, 0x3F));
        assert_eq!(phy_ctrl(1), PhyRequest::Read(1));
        // DIGITAL_OUT: mask<<8 | (~bits & mask).
        assert_eq!(digital_out(0x0F00 | (!0b0101u32 & 0xF)), (0xF, 0b0101));
        let d = dac(0xB000_9000);
        assert!(d.valid && d.amp_request == Some(true) && d.command == 0x9000);
        assert_eq!(dac(0x8000_8000).amp_request, None);
        assert_eq!(hub_header_rev8(33, 0x1234, true, 100_000), 0x2134_FFFF);
        assert_eq!(write_header(0x0306), (3, 6));
    }
}
