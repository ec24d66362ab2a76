//! STATUS (`fpga-board.md` §2): the word the board reports on read (StatusRead),
//! the command word written to it (StatusWrite) and the meaning of a write (per-
//! axis amplifier commands, power, relay, reboot) as StatusCommand.

use super::*;

quadlet_register! {
    /// STATUS as read (`fpga-board.md` §2 "STATUS read", QLA1 Rev 7/8). The
    /// emulated board builds it with the `with_*` builders; the host reads it.
    pub struct StatusRead {
        /// Number of axes, bits 31:28 (4 on a QLA1).
        axes, set_axes, with_axes: u8 = field::STATUS_AXES;
        /// Board ID from the rotary switch, bits 27:24 (0..=15).
        board_id, set_board_id, with_board_id: u8 = field::STATUS_BOARD_ID;
        /// The watchdog timed out, bit 23 (§7).
        watchdog_timeout, set_watchdog_timeout, with_watchdog_timeout: bool =
            field::STATUS_WATCHDOG_TIMEOUT;
        /// A quad DAC is present, bit 22.
        quad_dac, set_quad_dac, with_quad_dac: bool = field::STATUS_QUAD_DAC;
        /// The digital-output configuration check is done, bit 21
        /// (`fpga-board-extras.md` §3).
        dout_checked, set_dout_checked, with_dout_checked: bool = field::STATUS_DOUT_CHECKED;
        /// Bidirectional digital-output hardware (QLA 1.4+), bit 20
        /// (`fpga-board-extras.md` §3).
        dout_bidirectional, set_dout_bidirectional, with_dout_bidirectional: bool =
            field::STATUS_DOUT_BIDIRECTIONAL;
        /// The motor supply is good, bit 19.
        motor_supply_good, set_motor_supply_good, with_motor_supply_good: bool =
            field::STATUS_MOTOR_SUPPLY_GOOD;
        /// Motor power is enabled, bit 18.
        motor_power_enabled, set_motor_power_enabled, with_motor_power_enabled: bool =
            field::STATUS_MOTOR_POWER_ENABLED;
        /// Safety relay state (as sensed), bit 17.
        relay_state, set_relay_state, with_relay_state: bool = field::STATUS_RELAY_STATE;
        /// Safety relay switched on (as commanded), bit 16.
        relay_on, set_relay_on, with_relay_on: bool = field::STATUS_RELAY_ON;
        /// Motor supply fault, bit 15.
        motor_supply_fault, set_motor_supply_fault, with_motor_supply_fault: bool =
            field::STATUS_SUPPLY_FAULT;
        /// Safety feedback, bit 14.
        safety_feedback, set_safety_feedback, with_safety_feedback: bool =
            field::STATUS_SAFETY_FEEDBACK;
        /// I/O expander present, bit 12.
        io_expander, set_io_expander, with_io_expander: bool = field::STATUS_IO_EXPANDER;
        /// Amplifier fault/status per axis, bits 11:8 (Rev < 8; Rev 8 reports
        /// it in MOTOR_STATUS).
        amp_fault, set_amp_fault, with_amp_fault: u8 = field::STATUS_AMP_FAULT;
        /// Safety amplifier disable per axis, bits 7:4.
        safety_amp_disable, set_safety_amp_disable, with_safety_amp_disable: u8 =
            field::STATUS_SAFETY_AMP_DISABLE;
        /// Amplifier enabled per axis (bit i = axis i + 1), bits 3:0.
        amp_enabled, set_amp_enabled, with_amp_enabled: u8 = field::STATUS_AMP_ENABLED;
    }
}

/// STATUS write: turn motor power on (`fpga-board.md` §2).
pub const STATUS_POWER_ON: u32 = 0x000C_0000;
/// STATUS write: turn motor power off (`fpga-board.md` §2).
pub const STATUS_POWER_OFF: u32 = 0x0008_0000;
/// STATUS write: switch the safety relay on (`fpga-board.md` §2).
pub const STATUS_RELAY_ON: u32 = 0x0003_0000;
/// STATUS write: switch the safety relay off (`fpga-board.md` §2).
pub const STATUS_RELAY_OFF: u32 = 0x0002_0000;
/// STATUS write: reboot the FPGA (Rev 7+, `fpga-board.md` §2).
pub const STATUS_REBOOT: u32 = 0x0030_0000;

quadlet_register! {
    /// STATUS as written, raw (`fpga-board.md` §2 "STATUS write"): mask/value
    /// pairs. [`command`](Self::command) gives its meaning.
    pub struct StatusWrite {
        /// Reboot bits 21:20 (both set = reboot, Rev 7+).
        reboot_bits, set_reboot_bits, with_reboot_bits: u8 = field::WRITE_REBOOT;
        /// Power-enable mask, bit 19.
        power_mask, set_power_mask, with_power_mask: bool = field::WRITE_POWER_MASK;
        /// Power-enable value, bit 18.
        power_value, set_power_value, with_power_value: bool = field::WRITE_POWER_VALUE;
        /// Safety-relay mask, bit 17.
        relay_mask, set_relay_mask, with_relay_mask: bool = field::WRITE_RELAY_MASK;
        /// Safety-relay value, bit 16.
        relay_value, set_relay_value, with_relay_value: bool = field::WRITE_RELAY_VALUE;
        /// Amplifier mask per axis, bits 11:8.
        amp_mask, set_amp_mask, with_amp_mask: u8 = field::WRITE_AMP_MASK;
        /// Amplifier enable values per axis, bits 3:0.
        amp_values, set_amp_values, with_amp_values: u8 = field::WRITE_AMP_VALUE;
    }
}

impl StatusWrite {
    /// What a direct quadlet write of this word to STATUS asks for.
    pub fn command(self) -> StatusCommand {
        StatusCommand::parse(self.0)
    }

    /// What this word asks for as the control quadlet of a real-time write
    /// block, where only bits 19:0 take effect (`fpga-board.md` §5): it can
    /// never reboot.
    pub fn block_command(self) -> StatusCommand {
        let effective = field::WRITE_BLOCK_EFFECTIVE;
        StatusCommand::parse(effective.insert(0, effective.extract(self.0)))
    }
}

/// Which amplifiers a STATUS write changes and to what
/// (`fpga-board.md` §2: mask bits 11:8, values bits 3:0).
///
/// Always canonical: 4-bit mask, enable bits only inside the mask.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct AmpCommand {
    mask: u8,
    enable: u8,
}

impl AmpCommand {
    /// Leave every amplifier as it is.
    pub const NONE: AmpCommand = AmpCommand { mask: 0, enable: 0 };

    /// Change the amplifiers in `mask` (bit i = axis i + 1) to the states in
    /// `enable`. Both are cut to 4 bits and `enable` to the mask.
    pub const fn new(mask: u8, enable: u8) -> AmpCommand {
        let mask = mask & 0xF;
        AmpCommand {
            mask,
            enable: enable & mask,
        }
    }

    /// The amplifiers to change.
    pub const fn mask(self) -> u8 {
        self.mask
    }

    /// Their new states (only bits inside the mask are set).
    pub const fn enable(self) -> u8 {
        self.enable
    }

    /// Whether nothing is changed.
    pub const fn is_none(self) -> bool {
        self.mask == 0
    }

    /// The requested state of the amplifier of 0-based axis `index`, or
    /// `None` when it is left alone (or `index` is beyond the 4 bits).
    pub fn axis(self, index: usize) -> Option<bool> {
        let bit = 1u8.checked_shl(u32::try_from(index).ok()?)?;
        (self.mask & bit != 0).then_some(self.enable & bit != 0)
    }
}

/// The meaning of a STATUS write: what to change, `None` meaning leave it
/// (`fpga-board.md` §2 "STATUS write"). An emulator applies only what was
/// asked.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct StatusCommand {
    /// Motor power: mask bit 19, value bit 18.
    pub power: Option<bool>,
    /// Safety relay: mask bit 17, value bit 16.
    pub relay: Option<bool>,
    /// Amplifiers: mask bits 11:8, values bits 3:0.
    pub amps: AmpCommand,
    /// Reboot the FPGA (bits 21:20 both set, Rev 7+).
    pub reboot: bool,
}

impl StatusCommand {
    /// Change nothing.
    pub const NONE: StatusCommand = StatusCommand {
        power: None,
        relay: None,
        amps: AmpCommand::NONE,
        reboot: false,
    };

    /// Switch motor power on or off.
    pub const fn power(on: bool) -> StatusCommand {
        StatusCommand {
            power: Some(on),
            ..Self::NONE
        }
    }

    /// Switch the safety relay on or off.
    pub const fn relay(on: bool) -> StatusCommand {
        StatusCommand {
            relay: Some(on),
            ..Self::NONE
        }
    }

    /// Change the amplifiers in `mask` to the states in `enable`.
    pub const fn amplifiers(mask: u8, enable: u8) -> StatusCommand {
        StatusCommand {
            amps: AmpCommand::new(mask, enable),
            ..Self::NONE
        }
    }

    /// Reboot the FPGA.
    pub const fn reboot() -> StatusCommand {
        StatusCommand {
            reboot: true,
            ..Self::NONE
        }
    }

    /// Decode a STATUS write word. Bits without meaning (a value bit whose
    /// mask bit is clear, a lone reboot bit, unused bits) are ignored as the
    /// firmware ignores them, so `parse(w).to_word()` is `w` without them.
    pub fn parse(word: u32) -> StatusCommand {
        let w = StatusWrite(word);
        StatusCommand {
            power: w.power_mask().then_some(w.power_value()),
            relay: w.relay_mask().then_some(w.relay_value()),
            amps: AmpCommand::new(w.amp_mask(), w.amp_values()),
            reboot: w.reboot_bits() == field::WRITE_REBOOT.max() as u8,
        }
    }

    /// Encode as the STATUS write word.
    #[inline]
    pub fn to_word(self) -> StatusWrite {
        let mut w = StatusWrite(0);
        if let Some(on) = self.power {
            w.set_power_mask(true);
            w.set_power_value(on);
        }
        if let Some(on) = self.relay {
            w.set_relay_mask(true);
            w.set_relay_value(on);
        }
        w.set_amp_mask(self.amps.mask());
        w.set_amp_values(self.amps.enable());
        if self.reboot {
            w.set_reboot_bits(field::WRITE_REBOOT.max() as u8);
        }
        w
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn status_read_every_field() {
        // Every field set through its builder, then read back.
        let s = StatusRead::default()
            .with_axes(4)
            .with_board_id(0xB)
            .with_watchdog_timeout(true)
            .with_quad_dac(true)
            .with_motor_supply_good(true)
            .with_motor_power_enabled(true)
            .with_relay_state(true)
            .with_relay_on(true)
            .with_motor_supply_fault(true)
            .with_safety_feedback(true)
            .with_io_expander(true)
            .with_amp_fault(0x9)
            .with_safety_amp_disable(0x6)
            .with_amp_enabled(0x3);
        assert_eq!(s.raw(), 0x4BCF_D963);
        assert_eq!(s.axes(), 4);
        assert_eq!(s.board_id(), 0xB);
        assert!(s.watchdog_timeout() && s.quad_dac() && s.motor_supply_good());
        assert!(s.motor_power_enabled() && s.relay_state() && s.relay_on());
        assert!(s.motor_supply_fault() && s.safety_feedback() && s.io_expander());
        assert_eq!(
            (s.amp_fault(), s.safety_amp_disable(), s.amp_enabled()),
            (9, 6, 3)
        );
        // Clearing one field leaves the others.
        let mut t = s;
        t.set_board_id(0);
        assert_eq!(t.raw(), 0x40CF_D963);
        // Setters truncate to the field width.
        t.set_axes(0x1F);
        assert_eq!(t.axes(), 0xF);
    }

    #[test]
    fn status_write_constants_from_the_spec() {
        assert_eq!(StatusCommand::power(true).to_word().raw(), STATUS_POWER_ON);
        assert_eq!(
            StatusCommand::power(false).to_word().raw(),
            STATUS_POWER_OFF
        );
        assert_eq!(StatusCommand::relay(true).to_word().raw(), STATUS_RELAY_ON);
        assert_eq!(
            StatusCommand::relay(false).to_word().raw(),
            STATUS_RELAY_OFF
        );
        assert_eq!(StatusCommand::reboot().to_word().raw(), STATUS_REBOOT);
        assert_eq!(STATUS_POWER_ON, 0x000C_0000);
        assert_eq!(STATUS_POWER_OFF, 0x0008_0000);
        assert_eq!(STATUS_RELAY_ON, 0x0003_0000);
        assert_eq!(STATUS_REBOOT, 0x0030_0000);
        // Amplifiers: mask<<8 | state.
        let c = StatusCommand::amplifiers(0b1010, 0b1000);
        assert_eq!(c.to_word().raw(), 0x0000_0A08);
        assert_eq!(c.amps.axis(3), Some(true));
        assert_eq!(c.amps.axis(1), Some(false));
        assert_eq!(c.amps.axis(0), None);
        assert_eq!(c.amps.axis(99), None);
        for (word, cmd) in [
            (STATUS_POWER_ON, StatusCommand::power(true)),
            (STATUS_POWER_OFF, StatusCommand::power(false)),
            (STATUS_RELAY_ON, StatusCommand::relay(true)),
            (STATUS_RELAY_OFF, StatusCommand::relay(false)),
            (STATUS_REBOOT, StatusCommand::reboot()),
            (0x0000_0A08, c),
            (0, StatusCommand::NONE),
        ] {
            assert_eq!(StatusCommand::parse(word), cmd);
            assert_eq!(StatusWrite(word).command(), cmd);
        }
    }

    #[test]
    fn status_write_ignores_meaningless_bits() {
        // Value bits without masks, a lone reboot bit, unused bits.
        let word = 0xFF14_F0F5;
        let c = StatusCommand::parse(word);
        assert_eq!(c.power, None);
        assert_eq!(c.relay, None);
        assert!(!c.reboot);
        assert_eq!(c.amps, AmpCommand::new(0x0, 0x5));
        assert!(c.amps.is_none());
        // A combined command, as the control quadlet of a write block.
        let both = STATUS_POWER_ON | STATUS_RELAY_ON | 0x0F0F | STATUS_REBOOT;
        let c = StatusWrite(both).command();
        assert!(c.reboot && c.power == Some(true) && c.relay == Some(true));
        let b = StatusWrite(both).block_command();
        assert!(!b.reboot);
        assert_eq!(b.power, Some(true));
        assert_eq!(b.amps, AmpCommand::new(0xF, 0xF));
        assert_eq!(StatusCommand::parse(both).to_word().raw(), both);
    }
}
