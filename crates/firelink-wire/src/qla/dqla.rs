//! Codecs of the DQLA (two QLAs on one FPGA V3): its STATUS and DIGIN
//! words, which differ from a QLA1's, and register 14 as its MAX7301 I/O
//! expanders answer it.
//!
//! Facts, read in jhu-cisst/mechatronics-firmware: `BoardRegs-DQLA.v`
//! (`reg_status`, `reg_digin`), `DQLA.v` (the expander IDs: MAX7317 1
//! and 2, MAX7301 3 and 4; the register-14 mux), `Max7301x2.v` (the
//! configuration and poll commands, the read-out word); and in
//! jhu-cisst/mechatronics-software: `AmpIO.cpp`
//! (`ReadMotorSupplyVoltageBit`: STATUS bit 4 + index - 1), `fpgatest.cpp`
//! (`DQLA_IOExp_Check`). Raw bits only.
//!
//! ```
//! use firelink_wire::qla::dqla::{DqlaStatus, Max7301Read, MAX7301_CONFIG};
//! // A DQLA with both QLAs' expanders found, power and relay on.
//! let s = DqlaStatus(0x8305_F303);
//! assert_eq!(s.board_id(), 3);
//! assert!(s.motor_power_enabled() && s.relay_on());
//! assert_eq!(s.dqla_expanders_ok(), 0b11);
//! assert_eq!(s.supply_comparators(), 0);
//! // DQLA_IOExp_Check reads back the first configuration command.
//! assert_eq!(MAX7301_CONFIG[0], 0x09FF);
//! assert_eq!(Max7301Read(0x4000_89FF).answer(), 0x89FF);
//! ```

use crate::qla::quadlet_register;

/// Bit fields, each defined once.
mod field {
    use crate::field::Field;

    // STATUS (BoardRegs-DQLA.v reg_status).
    pub const AXES: Field = Field::new(0, 31, 28);
    pub const BOARD_ID: Field = Field::new(0, 27, 24);
    pub const WATCHDOG: Field = Field::new(0, 23, 23);
    pub const QUAD_DAC: Field = Field::new(0, 22, 21);
    pub const SUPPLY_GOOD: Field = Field::new(0, 19, 19);
    pub const POWER: Field = Field::new(0, 18, 18);
    pub const RELAY: Field = Field::new(0, 16, 16);
    pub const SUPPLY_GOOD_EACH: Field = Field::new(0, 15, 14);
    pub const DQLA_EXP_OK: Field = Field::new(0, 13, 12);
    pub const DOUT_VALID: Field = Field::new(0, 11, 10);
    pub const DOUT_BIDIR: Field = Field::new(0, 9, 8);
    pub const SAFETY_FB: Field = Field::new(0, 7, 6);
    pub const SUPPLY_CMP: Field = Field::new(0, 5, 4);
    pub const WAVEFORM: Field = Field::new(0, 3, 3);
    pub const IOEXP_PRESENT: Field = Field::new(0, 1, 0);

    // DIGIN (BoardRegs-DQLA.v reg_digin).
    pub const DIN_OUTPUTS: Field = Field::new(0, 31, 24);
    pub const DIN_NEG: Field = Field::new(0, 23, 16);
    pub const DIN_POS: Field = Field::new(0, 15, 8);
    pub const DIN_HOME: Field = Field::new(0, 7, 0);

    // Register 14 from the MAX7301 pair (Max7301x2.v reg_rdata).
    pub const X_MARKER: Field = Field::new(0, 31, 29);
    pub const X_BUSY: Field = Field::new(0, 28, 28);
    pub const X_READ_WAITING: Field = Field::new(0, 27, 27);
    pub const X_PENDING: Field = Field::new(0, 26, 26);
    pub const X_READ_ERROR: Field = Field::new(0, 25, 25);
    pub const X_OUTPUT_ERROR: Field = Field::new(0, 24, 24);
    pub const X_NOT_OK: Field = Field::new(0, 23, 23);
    pub const X_NOT_DONE: Field = Field::new(0, 22, 22);
    pub const X_OUTPUT_MISMATCH: Field = Field::new(0, 20, 16);
    pub const X_ERROR_COUNT: Field = Field::new(0, 23, 16);
    pub const X_ANSWER: Field = Field::new(0, 15, 0);
}

quadlet_register! {
    /// STATUS of a DQLA (BoardRegs-DQLA.v): the bits a host shares with a
    /// QLA1 (axes, board ID, watchdog, supply good, power, relay) in their
    /// places, then per-QLA bits where a QLA1 has its amplifier fields.
    /// Bits of "each QLA" are QLA 1 in the lower bit, QLA 2 in the upper.
    pub struct DqlaStatus {
        /// Number of axes, bits 31:28 (8).
        axes, set_axes, with_axes: u8 = field::AXES;
        /// Board ID, bits 27:24.
        board_id, set_board_id, with_board_id: u8 = field::BOARD_ID;
        /// Watchdog timed out, bit 23.
        watchdog_timeout, set_watchdog_timeout, with_watchdog_timeout: bool = field::WATCHDOG;
        /// Each QLA's DAC is a quad LTC2604, bits 22:21.
        quad_dac, set_quad_dac, with_quad_dac: u8 = field::QUAD_DAC;
        /// Both QLAs' motor supplies good, bit 19.
        motor_supply_good, set_motor_supply_good, with_motor_supply_good: bool =
            field::SUPPLY_GOOD;
        /// Both QLAs' power enabled, bit 18.
        motor_power_enabled, set_motor_power_enabled, with_motor_power_enabled: bool =
            field::POWER;
        /// Safety relay on, bit 16.
        relay_on, set_relay_on, with_relay_on: bool = field::RELAY;
        /// Each QLA's motor supply good, bits 15:14.
        supply_good_each, set_supply_good_each, with_supply_good_each: u8 =
            field::SUPPLY_GOOD_EACH;
        /// Each QLA's MAX7301 (DQLA) expander found, bits 13:12.
        dqla_expanders_ok, set_dqla_expanders_ok, with_dqla_expanders_ok: u8 =
            field::DQLA_EXP_OK;
        /// Each QLA's digital output check done, bits 11:10.
        dout_checked, set_dout_checked, with_dout_checked: u8 = field::DOUT_VALID;
        /// Each QLA's digital outputs bidirectional, bits 9:8.
        dout_bidirectional, set_dout_bidirectional, with_dout_bidirectional: u8 =
            field::DOUT_BIDIR;
        /// Each QLA's safety line carries voltage, bits 7:6.
        safety_feedback, set_safety_feedback, with_safety_feedback: u8 = field::SAFETY_FB;
        /// Each QLA's motor-supply comparator (axis 4 / 8 DAC below the
        /// supply), bits 5:4.
        supply_comparators, set_supply_comparators, with_supply_comparators: u8 =
            field::SUPPLY_CMP;
        /// The waveform table drives an output, bit 3.
        waveform_active, set_waveform_active, with_waveform_active: bool = field::WAVEFORM;
        /// Each QLA's MAX7317 expander found (QLA 1.5+), bits 1:0.
        io_expanders, set_io_expanders, with_io_expanders: u8 = field::IOEXP_PRESENT;
    }
}

impl DqlaStatus {
    /// What `AmpIO::ReadMotorSupplyVoltageBit(index)` reads for a DQLA:
    /// `status & (index << 4)`, index 1 or 2 (0 for any other index).
    pub fn supply_comparator(self, index: u8) -> bool {
        matches!(index, 1 | 2) && self.0 & (u32::from(index) << 4) != 0
    }
}

quadlet_register! {
    /// DIGIN of a DQLA (BoardRegs-DQLA.v): the eight raw digital outputs
    /// and eight of each switch input (axis 1 in bit 0).
    pub struct DqlaDigitalIn {
        /// Raw digital outputs 8..1, bits 31:24.
        outputs, set_outputs, with_outputs: u8 = field::DIN_OUTPUTS;
        /// Negative limits, bits 23:16.
        neg_limits, set_neg_limits, with_neg_limits: u8 = field::DIN_NEG;
        /// Positive limits, bits 15:8.
        pos_limits, set_pos_limits, with_pos_limits: u8 = field::DIN_POS;
        /// Home switches, bits 7:0.
        home, set_home, with_home: u8 = field::DIN_HOME;
    }
}

/// Register-14 expander IDs on a DQLA (DQLA.v): QLA 1's and QLA 2's
/// MAX7317, then QLA 1's and QLA 2's MAX7301.
pub const DQLA_MAX7317_IDS: [u8; 2] = [1, 2];
/// See [`DQLA_MAX7317_IDS`].
pub const DQLA_MAX7301_IDS: [u8; 2] = [3, 4];

/// The commands the firmware configures each MAX7301 with at power-up,
/// in order (Max7301x2.v `ConfigCommands`; fpgatest checks each by reading
/// its register back): port groups 7:4, 11:8 inputs with pull-up, 15:12
/// outputs, 16 output and 19:17 inputs, 23:20 and 27:24 inputs, 31:28
/// outputs, then normal operation.
pub const MAX7301_CONFIG: [u16; 8] = [
    0x09FF, 0x0AFF, 0x0B55, 0x0C57, 0x0DFF, 0x0EFF, 0x0F55, 0x0401,
];

/// Register-14 marker bits 31:29 of an expander's read-out (`010`).
pub const MAX7301_READ_MARKER: u8 = 0b010;

quadlet_register! {
    /// Register 14 as a DQLA's MAX7301 pair answers it, normal read-out
    /// (Max7301x2.v). In the debug read-out bits 23:16 are the output
    /// error count instead.
    pub struct Max7301Read {
        /// `010`, bits 31:29.
        marker, set_marker, with_marker: u8 = field::X_MARKER;
        /// SPI busy, bit 28.
        busy, set_busy, with_busy: bool = field::X_BUSY;
        /// A host read awaits its answer, bit 27.
        read_waiting, set_read_waiting, with_read_waiting: bool = field::X_READ_WAITING;
        /// A host command is pending, bit 26.
        pending, set_pending, with_pending: bool = field::X_PENDING;
        /// A poll read failed, bit 25.
        read_error, set_read_error, with_read_error: bool = field::X_READ_ERROR;
        /// An output reads back other than commanded, bit 24.
        output_error, set_output_error, with_output_error: bool = field::X_OUTPUT_ERROR;
        /// The chip was not found ("failed to initialize"), bit 23.
        not_found, set_not_found, with_not_found: bool = field::X_NOT_OK;
        /// The configuration has not run ("not configured"), bit 22.
        not_configured, set_not_configured, with_not_configured: bool = field::X_NOT_DONE;
        /// Which outputs 16:12 mismatch, bits 20:16.
        output_mismatch, set_output_mismatch, with_output_mismatch: u8 =
            field::X_OUTPUT_MISMATCH;
        /// Debug read-out: the output error count, bits 23:16.
        error_count, set_error_count, with_error_count: u8 = field::X_ERROR_COUNT;
        /// The answer to the host's last read command: 15:8 the command's
        /// upper byte (`0x80 | register`), 7:0 the data.
        answer, set_answer, with_answer: u16 = field::X_ANSWER;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// BoardRegs-DQLA.v's byte layout, checked against words built from it:
    /// byte 2 {wdog, quad DAC x2, 0, mv_good both, power both, 0, relay},
    /// byte 1 {mv_good x2, exp ok x2, dout valid x2, bidir x2}, byte 0
    /// {safety x2, mv_fb x2, waveform, 0, ioexp x2}.
    #[test]
    fn status_fields_sit_where_boardregs_dqla_puts_them() {
        let s = DqlaStatus::default()
            .with_axes(8)
            .with_board_id(0xA)
            .with_watchdog_timeout(true)
            .with_quad_dac(0b11)
            .with_motor_supply_good(true)
            .with_motor_power_enabled(true)
            .with_relay_on(true)
            .with_supply_good_each(0b11)
            .with_dqla_expanders_ok(0b11)
            .with_dout_checked(0b11)
            .with_dout_bidirectional(0b11)
            .with_safety_feedback(0b11)
            .with_supply_comparators(0b10)
            .with_waveform_active(true)
            .with_io_expanders(0b11);
        assert_eq!(s.raw(), 0x8AED_FFEB);
        assert!(s.supply_comparator(2) && !s.supply_comparator(1));
        assert!(!s.supply_comparator(0) && !s.supply_comparator(3));
        let d = DqlaDigitalIn::default()
            .with_outputs(0x81)
            .with_neg_limits(0x42)
            .with_pos_limits(0x24)
            .with_home(0x18);
        assert_eq!(d.raw(), 0x8142_2418);
        let r = Max7301Read::default()
            .with_marker(MAX7301_READ_MARKER)
            .with_not_configured(true)
            .with_answer(0x8C57);
        assert_eq!(r.raw(), 0x4040_8C57);
        assert_eq!(Max7301Read(0x00FF_0000).error_count(), 0xFF);
    }
}
