//! The per-axis words (`fpga-board.md` §3): ADC, DAC, the encoder counter and
//! its timing words (offset-binary counts, preload, period, quarter, run) and
//! the motor configuration and status words.

use super::*;

quadlet_register! {
    /// ADC of one axis (`fpga-board.md` §3).
    pub struct AdcWord {
        /// Potentiometer, bits 31:16.
        pot, set_pot, with_pot: u16 = field::ADC_POT;
        /// Motor current, bits 15:0.
        current, set_current, with_current: u16 = field::ADC_CURRENT;
    }
}

// ------------------------------------------------------------------ DAC ---

/// DAC command of zero current (`fpga-board.md` §3).
pub const DAC_ZERO: u16 = 0x8000;

quadlet_register! {
    /// DAC write of one axis, also the per-motor quadlet of the real-time
    /// write block (`fpga-board.md` §3, §5).
    pub struct DacWord {
        /// The command is valid, bit 31.
        valid, set_valid, with_valid: bool = field::DAC_VALID;
        /// Rev 8: bit 28 is to be applied, bit 29.
        amp_enable_mask, set_amp_enable_mask, with_amp_enable_mask: bool =
            field::DAC_AMP_ENABLE_MASK;
        /// Rev 8: amplifier enable, bit 28.
        amp_enable, set_amp_enable, with_amp_enable: bool = field::DAC_AMP_ENABLE;
        /// Rev 7 real-time write block only: the board ID, bits 27:24.
        board_id, set_board_id, with_board_id: u8 = field::DAC_BOARD_ID;
        /// Rev 8: the control mode, bits 27:24 (0 current, 1 voltage with
        /// an I/O expander; MotorChannelQLA.v).
        control_mode, set_control_mode, with_control_mode: u8 = field::DAC_CONTROL_MODE;
        /// Current command, bits 15:0 ([`DAC_ZERO`] = zero current).
        command, set_command, with_command: u16 = field::DAC_COMMAND;
    }
}

impl DacWord {
    /// A valid command word (other bits zero).
    #[inline]
    pub fn valid_command(command: u16) -> DacWord {
        DacWord::default().with_valid(true).with_command(command)
    }

    /// Rev 8: the amplifier state requested, `None` when bit 29 is clear.
    #[inline]
    pub fn amp_request(self) -> Option<bool> {
        self.amp_enable_mask().then_some(self.amp_enable())
    }

    /// Rev 8: this word requesting `request` (`None` clears bits 29 and 28).
    #[must_use]
    #[inline]
    pub fn with_amp_request(self, request: Option<bool>) -> DacWord {
        self.with_amp_enable_mask(request.is_some())
            .with_amp_enable(request.unwrap_or(false))
    }
}

// -------------------------------------------------------------- Encoder ---

/// The neutral (zero-count) value of the 24-bit encoder counter and preload
/// (`fpga-board.md` §3).
pub const ENC_NEUTRAL: u32 = 0x80_0000;

/// Smallest signed count the 24-bit offset-binary counter holds.
pub const ENC_COUNTS_MIN: i32 = -(ENC_NEUTRAL as i32);
/// Largest signed count the 24-bit offset-binary counter holds.
pub const ENC_COUNTS_MAX: i32 = ENC_NEUTRAL as i32 - 1;

/// Signed counts of a 24-bit offset-binary count (bits above 23 ignored).
#[inline]
pub fn counts_from_offset_binary(raw: u32) -> i32 {
    field::ENC_COUNT.extract(raw) as i32 - ENC_NEUTRAL as i32
}

/// The 24-bit offset-binary count of a signed count.
///
/// # Errors
/// [`Error::OutOfRange`] outside [`ENC_COUNTS_MIN`]..=[`ENC_COUNTS_MAX`].
pub fn offset_binary_from_counts(counts: i32) -> Result<u32> {
    if !(ENC_COUNTS_MIN..=ENC_COUNTS_MAX).contains(&counts) {
        return Err(Error::OutOfRange {
            what: "encoder counts",
            value: i64::from(counts),
            min: i64::from(ENC_COUNTS_MIN),
            max: i64::from(ENC_COUNTS_MAX),
        });
    }
    Ok((counts + ENC_NEUTRAL as i32) as u32)
}

/// The 24-bit offset-binary count of any signed count, wrapping modulo
/// 2^24 as the hardware counter does.
pub fn offset_binary_wrapping(counts: i64) -> u32 {
    (counts.wrapping_add(i64::from(ENC_NEUTRAL)) as u32) & field::ENC_COUNT.max()
}

quadlet_register! {
    /// ENC_PRELOAD write (`fpga-board.md` §3).
    pub struct EncPreload {
        /// The 24-bit preload, bits 23:0 ([`ENC_NEUTRAL`] = zero counts).
        value, set_value, with_value: u32 = field::ENC_COUNT;
    }
}

impl EncPreload {
    /// The preload as signed counts.
    pub fn counts(self) -> i32 {
        counts_from_offset_binary(self.value())
    }

    /// A preload of `counts`.
    ///
    /// # Errors
    /// [`Error::OutOfRange`] outside the 24-bit range.
    pub fn from_counts(counts: i32) -> Result<EncPreload> {
        Ok(EncPreload::default().with_value(offset_binary_from_counts(counts)?))
    }
}

quadlet_register! {
    /// ENC_POSITION (`fpga-board.md` §3).
    pub struct EncPosition {
        /// The count, bits 23:0, offset-binary around [`ENC_NEUTRAL`].
        count, set_count, with_count: u32 = field::ENC_COUNT;
        /// Counter overflow, bit 24.
        overflow, set_overflow, with_overflow: bool = field::ENC_OVERFLOW;
        /// Rev 8: index line, bit 30.
        index, set_index, with_index: bool = field::ENC_INDEX;
        /// Rev 8: B line, bit 29.
        b, set_b, with_b: bool = field::ENC_B;
        /// Rev 8: A line, bit 28.
        a, set_a, with_a: bool = field::ENC_A;
    }
}

impl EncPosition {
    /// The count as signed counts around the neutral value.
    #[inline]
    pub fn counts(self) -> i32 {
        counts_from_offset_binary(self.count())
    }

    /// This word with the count set to signed `counts`.
    ///
    /// # Errors
    /// [`Error::OutOfRange`] outside the 24-bit range.
    pub fn with_counts(self, counts: i32) -> Result<EncPosition> {
        Ok(self.with_count(offset_binary_from_counts(counts)?))
    }

    /// This word with the count set to `counts` modulo 2^24 (the hardware
    /// counter wraps; the overflow bit is the caller's to set).
    #[must_use]
    pub fn with_counts_wrapping(self, counts: i64) -> EncPosition {
        self.with_count(offset_binary_wrapping(counts))
    }
}

quadlet_register! {
    /// ENC_PERIOD, Rev 7+ (`fpga-board.md` §3).
    pub struct EncPeriod {
        /// Period in 49.152 MHz clocks, bits 25:0.
        period, set_period, with_period: u32 = field::ENC_TIME;
        /// Period overflow, bit 31.
        overflow, set_overflow, with_overflow: bool = field::ENC_TIME_OVERFLOW;
        /// Direction, bit 30.
        direction, set_direction, with_direction: bool = field::ENC_DIRECTION;
        /// Direction changed, bit 29.
        direction_changed, set_direction_changed, with_direction_changed: bool =
            field::ENC_DIRECTION_CHANGED;
        /// Encoder error, bit 28.
        error, set_error, with_error: bool = field::ENC_ERROR;
        /// Partial period, bit 27.
        partial, set_partial, with_partial: bool = field::ENC_PARTIAL;
    }
}

quadlet_register! {
    /// ENC_QTR1 or ENC_QTR5: a quarter-cycle period (`fpga-board.md` §3).
    pub struct EncQuarter {
        /// Quarter-cycle period in clocks, bits 25:0.
        period, set_period, with_period: u32 = field::ENC_TIME;
        /// Overflow, bit 31.
        overflow, set_overflow, with_overflow: bool = field::ENC_TIME_OVERFLOW;
        /// Direction, bit 30.
        direction, set_direction, with_direction: bool = field::ENC_DIRECTION;
        /// Edge mask, bits 29:26.
        edges, set_edges, with_edges: u8 = field::ENC_EDGES;
    }
}

quadlet_register! {
    /// ENC_RUN: clocks since the last encoder edge (`fpga-board.md` §3).
    pub struct EncRun {
        /// Clocks since the last edge, bits 25:0.
        clocks, set_clocks, with_clocks: u32 = field::ENC_TIME;
        /// Overflow, bit 31.
        overflow, set_overflow, with_overflow: bool = field::ENC_TIME_OVERFLOW;
    }
}

// ---------------------------------------------------------------- Motor ---

quadlet_register! {
    /// MOTOR_CONFIG (`fpga-board.md` §3; Rev 8 MotorChannelQLA.v). Bits
    /// 25 and 24 read as what the board can do and, written, say which of
    /// the delay and the limit to load.
    pub struct MotorConfig {
        /// Read and write: the current safety check is off, bit 31.
        disable_safety, set_disable_safety, with_disable_safety: bool =
            field::MCFG_DISABLE_SAFETY;
        /// Read and write: the follower op amp is forced on, bit 30.
        force_disable, set_force_disable, with_force_disable: bool = field::MCFG_FORCE_DISABLE;
        /// Read: voltage mode available (an I/O expander), bit 25.
        voltage_mode, set_voltage_mode, with_voltage_mode: bool = field::MCFG_VOLTAGE_MODE;
        /// Read: current mode available, bit 24.
        current_mode, set_current_mode, with_current_mode: bool = field::MCFG_CURRENT_MODE;
        /// Write: load the enable delay (bits 23:16), bit 25.
        load_delay, set_load_delay, with_load_delay: bool = field::MCFG_VOLTAGE_MODE;
        /// Write: load the current limit (bits 14:0), bit 24.
        load_limit, set_load_limit, with_load_limit: bool = field::MCFG_CURRENT_MODE;
        /// Amplifier enable delay, bits 23:16.
        enable_delay, set_enable_delay, with_enable_delay: u8 = field::MCFG_ENABLE_DELAY;
        /// Current limit, bits 15:0.
        current_limit, set_current_limit, with_current_limit: u16 = field::MCFG_CURRENT_LIMIT;
    }
}

quadlet_register! {
    /// MOTOR_STATUS (Rev 8, `fpga-board.md` §3).
    pub struct MotorStatus {
        /// Amplifier on, bit 29.
        amp_on, set_amp_on, with_amp_on: bool = field::MSTAT_AMP_ON;
        /// Amplifier requested on, bit 28.
        amp_requested, set_amp_requested, with_amp_requested: bool = field::MSTAT_AMP_REQUESTED;
        /// The control mode in effect, bits 27:24.
        control_mode, set_control_mode, with_control_mode: u8 = field::MSTAT_CONTROL_MODE;
        /// Current control (not voltage control), bit 20.
        current_control, set_current_control, with_current_control: bool =
            field::MSTAT_CURRENT_CONTROL;
        /// Disabled by the safety chain, bit 17.
        safety_disable, set_safety_disable, with_safety_disable: bool =
            field::MSTAT_SAFETY_DISABLE;
        /// Amplifier fault, bit 16.
        amp_fault, set_amp_fault, with_amp_fault: bool = field::MSTAT_AMP_FAULT;
        /// The current command in effect, bits 15:0.
        current_command, set_current_command, with_current_command: u16 =
            field::MSTAT_CURRENT_COMMAND;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dac_word() {
        let d = DacWord::valid_command(DAC_ZERO);
        assert_eq!(d.raw(), 0x8000_8000);
        let d = d.with_amp_request(Some(true));
        assert_eq!(d.raw(), 0xB000_8000);
        assert_eq!(d.amp_request(), Some(true));
        assert_eq!(d.with_amp_request(Some(false)).raw(), 0xA000_8000);
        assert_eq!(d.with_amp_request(None).amp_request(), None);
        assert_eq!(d.with_board_id(5).raw(), 0xB500_8000);
    }

    #[test]
    fn encoder_counts() {
        assert_eq!(counts_from_offset_binary(ENC_NEUTRAL), 0);
        assert_eq!(counts_from_offset_binary(0), ENC_COUNTS_MIN);
        assert_eq!(counts_from_offset_binary(0xFF_FFFF), ENC_COUNTS_MAX);
        assert_eq!(offset_binary_from_counts(-1), Ok(0x7F_FFFF));
        assert!(offset_binary_from_counts(ENC_COUNTS_MAX + 1).is_err());
        assert!(offset_binary_from_counts(ENC_COUNTS_MIN - 1).is_err());
        assert_eq!(offset_binary_wrapping(1 << 23), 0);
        assert_eq!(offset_binary_wrapping(-(1 << 23) - 1), 0xFF_FFFF);
        let p = EncPosition::default()
            .with_counts(-10)
            .unwrap()
            .with_overflow(true)
            .with_index(true)
            .with_a(true);
        assert_eq!(p.raw(), 0x5100_0000 | 0x7F_FFF6);
        assert_eq!(p.counts(), -10);
        assert!(p.index() && !p.b() && p.a() && p.overflow());
        assert_eq!(
            EncPosition(0xFFFF_FFFF).with_counts_wrapping(0).raw(),
            0xFF80_0000
        );
        assert_eq!(EncPreload::from_counts(0), Ok(EncPreload(ENC_NEUTRAL)));
        assert_eq!(EncPreload(0xFF80_0001).counts(), 1);
    }

    #[test]
    fn encoder_timing_words() {
        let p = EncPeriod::default()
            .with_period(0x3FF_FFFF)
            .with_overflow(true)
            .with_direction(true)
            .with_direction_changed(true)
            .with_error(true)
            .with_partial(true);
        assert_eq!(p.raw(), 0xFBFF_FFFF);
        let q = EncQuarter::default().with_edges(0xF).with_period(1);
        assert_eq!(q.raw(), 0x3C00_0001);
        assert!(EncQuarter(0x8000_0000).overflow());
        let r = EncRun::default().with_clocks(0x123).with_overflow(true);
        assert_eq!(r.raw(), 0x8000_0123);
    }

    #[test]
    fn motor_words() {
        let c = MotorConfig::default()
            .with_voltage_mode(true)
            .with_current_mode(true)
            .with_enable_delay(0x78)
            .with_current_limit(0x1234);
        assert_eq!(c.raw(), 0x0378_1234);
        let s = MotorStatus::default()
            .with_amp_on(true)
            .with_amp_requested(true)
            .with_safety_disable(true)
            .with_amp_fault(true)
            .with_current_command(0x8000);
        assert_eq!(s.raw(), 0x3003_8000);
    }
}
