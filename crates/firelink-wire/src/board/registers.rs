//! Typed codecs for the register quadlets of the board (`fpga-board.md` §2,
//! §3). Raw bits only: no physical units.
//!
//! Most registers are `u32` newtypes (every bit pattern is a valid raw
//! quadlet) whose bit fields each have a getter, a setter and a builder,
//! defined from one [`Field`](crate::field::Field) in the private `field`
//! module. Write-only command encodings that carry a choice (STATUS write,
//! PHY_CTRL, DIGITAL_OUT) also have a meaning type with `parse`/`to_word`.
//!
//! ```
//! use firelink_wire::board::registers::{StatusCommand, StatusRead};
//! // The emulator builds STATUS; the host reads it.
//! let status = StatusRead::default().with_axes(4).with_board_id(3).with_amp_enabled(0b0101);
//! assert_eq!(status.raw(), 0x4300_0005);
//! // Turn motor power on (fpga-board.md §2: 0x000C0000).
//! assert_eq!(StatusCommand::power(true).to_word().raw(), 0x000C_0000);
//! ```

use core::net::Ipv4Addr;
use core::time::Duration;

use crate::board::{check_max, quadlet_register};
use crate::error::{Error, Result};
use crate::open_enum::open_enum;

/// Bit fields of the register quadlets, each defined once
/// (`fpga-board.md` §2 and §3).
mod field {
    use crate::field::Field;

    // STATUS read (§2 "STATUS read").
    pub const STATUS_AXES: Field = Field::new(0, 31, 28);
    pub const STATUS_BOARD_ID: Field = Field::new(0, 27, 24);
    pub const STATUS_WATCHDOG_TIMEOUT: Field = Field::new(0, 23, 23);
    pub const STATUS_QUAD_DAC: Field = Field::new(0, 22, 22);
    pub const STATUS_DOUT_CHECKED: Field = Field::new(0, 21, 21);
    pub const STATUS_DOUT_BIDIRECTIONAL: Field = Field::new(0, 20, 20);
    pub const STATUS_MOTOR_SUPPLY_GOOD: Field = Field::new(0, 19, 19);
    pub const STATUS_MOTOR_POWER_ENABLED: Field = Field::new(0, 18, 18);
    pub const STATUS_RELAY_STATE: Field = Field::new(0, 17, 17);
    pub const STATUS_RELAY_ON: Field = Field::new(0, 16, 16);
    pub const STATUS_SUPPLY_FAULT: Field = Field::new(0, 15, 15);
    pub const STATUS_SAFETY_FEEDBACK: Field = Field::new(0, 14, 14);
    pub const STATUS_IO_EXPANDER: Field = Field::new(0, 12, 12);
    pub const STATUS_AMP_FAULT: Field = Field::new(0, 11, 8);
    pub const STATUS_SAFETY_AMP_DISABLE: Field = Field::new(0, 7, 4);
    pub const STATUS_AMP_ENABLED: Field = Field::new(0, 3, 0);

    // STATUS write (§2 "STATUS write").
    pub const WRITE_REBOOT: Field = Field::new(0, 21, 20);
    pub const WRITE_POWER_MASK: Field = Field::new(0, 19, 19);
    pub const WRITE_POWER_VALUE: Field = Field::new(0, 18, 18);
    pub const WRITE_RELAY_MASK: Field = Field::new(0, 17, 17);
    pub const WRITE_RELAY_VALUE: Field = Field::new(0, 16, 16);
    pub const WRITE_AMP_MASK: Field = Field::new(0, 11, 8);
    pub const WRITE_AMP_VALUE: Field = Field::new(0, 3, 0);
    /// The bits of a real-time block's control quadlet that take effect (§5).
    pub const WRITE_BLOCK_EFFECTIVE: Field = Field::new(0, 19, 0);

    // PHY_CTRL / PHY_DATA (§2).
    pub const PHY_CTRL_WRITE: Field = Field::new(0, 12, 12);
    pub const PHY_CTRL_REGISTER: Field = Field::new(0, 11, 8);
    pub const PHY_CTRL_DATA: Field = Field::new(0, 7, 0);
    pub const PHY_CTRL_READ_REGISTER: Field = Field::new(0, 3, 0);
    pub const PHY_DATA_REGISTER: Field = Field::new(0, 11, 8);
    pub const PHY_DATA_DATA: Field = Field::new(0, 7, 0);

    // WATCHDOG (§2).
    pub const WATCHDOG_TICKS: Field = Field::new(0, 15, 0);
    pub const WATCHDOG_LED: Field = Field::new(0, 31, 31);

    // TEMPERATURE (§2).
    pub const TEMPERATURE_UPPER: Field = Field::new(0, 15, 8);
    pub const TEMPERATURE_LOWER: Field = Field::new(0, 7, 0);

    // DIGITAL_OUT write and read (extras §3).
    pub const DOUT_PLAY: Field = Field::new(0, 31, 31);
    pub const DOUT_MASK: Field = Field::new(0, 11, 8);
    pub const DOUT_RAW: Field = Field::new(0, 3, 0);
    pub const DOUT_TABLE_ACTIVE: Field = Field::new(0, 31, 31);
    pub const DOUT_TABLE_VALID: Field = Field::new(0, 30, 30);
    pub const DOUT_TABLE_INDEX: Field = Field::new(0, 25, 16);
    pub const DOUT_EXTRA_IO: Field = Field::new(0, 11, 8);

    // DOUT_CTRL, axis offset 8 (extras §3).
    pub const DOUT_CTRL_HIGH: Field = Field::new(0, 31, 16);
    pub const DOUT_CTRL_LOW: Field = Field::new(0, 15, 0);

    // Waveform table entry (extras §3).
    pub const WAVE_VALID: Field = Field::new(0, 31, 31);
    pub const WAVE_END_COUNT: Field = Field::new(0, 30, 8);
    pub const WAVE_OUTPUTS: Field = Field::new(0, 7, 0);

    // DIGITAL_IN (§2).
    pub const DIN_V_FAULT: Field = Field::new(0, 31, 31);
    pub const DIN_WAVEFORM: Field = Field::new(0, 29, 29);
    pub const DIN_SUPPLY_COMPARATOR: Field = Field::new(0, 28, 28);
    pub const DIN_ENC_A: Field = Field::new(0, 27, 24);
    pub const DIN_ENC_B: Field = Field::new(0, 23, 20);
    pub const DIN_INDEX: Field = Field::new(0, 19, 16);
    pub const DIN_OUTPUTS: Field = Field::new(0, 15, 12);
    pub const DIN_NEG_LIMITS: Field = Field::new(0, 11, 8);
    pub const DIN_POS_LIMITS: Field = Field::new(0, 7, 4);
    pub const DIN_HOME: Field = Field::new(0, 3, 0);

    // ETH_STATUS (§2).
    pub const ETH_V2: Field = Field::new(0, 31, 31);
    pub const ETH_VERSION_BITS: Field = Field::new(0, 31, 30);

    // GIT_DESC (§2).
    pub const GIT_COMMIT: Field = Field::new(0, 31, 4);
    pub const GIT_DIRTY: Field = Field::new(0, 3, 3);

    // ADC (§3).
    pub const ADC_POT: Field = Field::new(0, 31, 16);
    pub const ADC_CURRENT: Field = Field::new(0, 15, 0);

    // DAC (§3).
    pub const DAC_VALID: Field = Field::new(0, 31, 31);
    pub const DAC_AMP_ENABLE_MASK: Field = Field::new(0, 29, 29);
    pub const DAC_AMP_ENABLE: Field = Field::new(0, 28, 28);
    pub const DAC_BOARD_ID: Field = Field::new(0, 27, 24);
    pub const DAC_CONTROL_MODE: Field = Field::new(0, 27, 24);
    pub const DAC_COMMAND: Field = Field::new(0, 15, 0);

    // ENC_PRELOAD / ENC_POSITION (§3).
    pub const ENC_COUNT: Field = Field::new(0, 23, 0);
    pub const ENC_OVERFLOW: Field = Field::new(0, 24, 24);
    pub const ENC_INDEX: Field = Field::new(0, 30, 30);
    pub const ENC_B: Field = Field::new(0, 29, 29);
    pub const ENC_A: Field = Field::new(0, 28, 28);

    // ENC_PERIOD, ENC_QTR1/5, ENC_RUN (§3).
    pub const ENC_TIME: Field = Field::new(0, 25, 0);
    pub const ENC_TIME_OVERFLOW: Field = Field::new(0, 31, 31);
    pub const ENC_DIRECTION: Field = Field::new(0, 30, 30);
    pub const ENC_DIRECTION_CHANGED: Field = Field::new(0, 29, 29);
    pub const ENC_ERROR: Field = Field::new(0, 28, 28);
    pub const ENC_PARTIAL: Field = Field::new(0, 27, 27);
    pub const ENC_EDGES: Field = Field::new(0, 29, 26);

    // MOTOR_CONFIG (§3).
    pub const MCFG_DISABLE_SAFETY: Field = Field::new(0, 31, 31);
    pub const MCFG_FORCE_DISABLE: Field = Field::new(0, 30, 30);
    pub const MCFG_VOLTAGE_MODE: Field = Field::new(0, 25, 25);
    pub const MCFG_CURRENT_MODE: Field = Field::new(0, 24, 24);
    pub const MCFG_ENABLE_DELAY: Field = Field::new(0, 23, 16);
    pub const MCFG_CURRENT_LIMIT: Field = Field::new(0, 15, 0);

    // MOTOR_STATUS (§3).
    pub const MSTAT_AMP_ON: Field = Field::new(0, 29, 29);
    pub const MSTAT_AMP_REQUESTED: Field = Field::new(0, 28, 28);
    pub const MSTAT_CONTROL_MODE: Field = Field::new(0, 27, 24);
    pub const MSTAT_CURRENT_CONTROL: Field = Field::new(0, 20, 20);
    pub const MSTAT_SAFETY_DISABLE: Field = Field::new(0, 17, 17);
    pub const MSTAT_AMP_FAULT: Field = Field::new(0, 16, 16);
    pub const MSTAT_CURRENT_COMMAND: Field = Field::new(0, 15, 0);
}

/// The system clock of the board, 49.152 MHz (`fpga-board.md` §2, §4).
pub const SYSTEM_CLOCK_HZ: u32 = 49_152_000;

// ---------------------------------------------------------------- STATUS ---

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

// ----------------------------------------------------------- PHY access ---

/// A PHY register access requested through PHY_CTRL (`fpga-board.md` §2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PhyRequest {
    /// Read PHY register `register` (0..=15): the word is the register number.
    Read {
        /// The PHY register.
        register: u8,
    },
    /// Write `data` to PHY register `register`: `0x1000 | reg<<8 | data`.
    Write {
        /// The PHY register (0..=15).
        register: u8,
        /// The value written.
        data: u8,
    },
}

impl PhyRequest {
    /// Decode a PHY_CTRL write.
    ///
    /// # Errors
    /// [`Error::InvalidValue`] when bits are set that neither form carries
    /// (above bit 12 for a write; above bit 3 for a read).
    pub fn parse(word: u32) -> Result<PhyRequest> {
        let request = if field::PHY_CTRL_WRITE.extract(word) == 1 {
            PhyRequest::Write {
                register: field::PHY_CTRL_REGISTER.extract(word) as u8,
                data: field::PHY_CTRL_DATA.extract(word) as u8,
            }
        } else {
            PhyRequest::Read {
                register: field::PHY_CTRL_READ_REGISTER.extract(word) as u8,
            }
        };
        match request.to_word() {
            Ok(canonical) if canonical == word => Ok(request),
            _ => Err(Error::InvalidValue {
                what: "PHY_CTRL word",
                value: word,
            }),
        }
    }

    /// Encode as the PHY_CTRL word.
    ///
    /// # Errors
    /// [`Error::FieldRange`] for a register above 15.
    pub fn to_word(self) -> Result<u32> {
        match self {
            PhyRequest::Read { register } => {
                let f = field::PHY_CTRL_READ_REGISTER;
                check_max("PHY register", u64::from(register), u64::from(f.max()))?;
                Ok(f.insert(0, u32::from(register)))
            }
            PhyRequest::Write { register, data } => {
                let f = field::PHY_CTRL_REGISTER;
                check_max("PHY register", u64::from(register), u64::from(f.max()))?;
                let w = field::PHY_CTRL_WRITE.insert(0, 1);
                let w = f.insert(w, u32::from(register));
                Ok(field::PHY_CTRL_DATA.insert(w, u32::from(data)))
            }
        }
    }
}

quadlet_register! {
    /// PHY_DATA: the result of a PHY register read (`fpga-board.md` §2).
    pub struct PhyData {
        /// The PHY register read, bits 11:8.
        register, set_register, with_register: u8 = field::PHY_DATA_REGISTER;
        /// Its value, bits 7:0.
        data, set_data, with_data: u8 = field::PHY_DATA_DATA;
    }
}

// -------------------------------------------------------------- WATCHDOG ---

quadlet_register! {
    /// WATCHDOG: the period in ticks of 256 system clocks, 5.208 us
    /// (`fpga-board.md` §2, §7); 0 disables it.
    pub struct Watchdog {
        /// The period in ticks, bits 15:0.
        ticks, set_ticks, with_ticks: u16 = field::WATCHDOG_TICKS;
        /// Rev 8: which status the board's LED shows (the watchdog period
        /// when set), bit 31; stored and read back (BoardRegs.v).
        led_select, set_led_select, with_led_select: bool = field::WATCHDOG_LED;
    }
}

impl Watchdog {
    /// System clocks per watchdog tick.
    pub const CLOCKS_PER_TICK: u32 = 256;
    /// The watchdog is off.
    pub const DISABLED: Watchdog = Watchdog(0);
    /// The period after power-up: `0x1680` ticks = 30 ms (`fpga-board.md` §2).
    pub const POWER_UP: Watchdog = Watchdog(0x1680);

    /// Nanoseconds per tick are 256e9 / 49.152e6 = 15625 / 3 exactly.
    const TICK_NS_NUM: u128 = 15_625;
    const TICK_NS_DEN: u128 = 3;

    /// Whether the watchdog is off.
    pub fn is_disabled(self) -> bool {
        self.ticks() == 0
    }

    /// The period as a duration (zero when disabled), rounded down to
    /// whole nanoseconds.
    pub fn period(self) -> Duration {
        let ns = u128::from(self.ticks()) * Self::TICK_NS_NUM / Self::TICK_NS_DEN;
        Duration::from_nanos(ns as u64)
    }

    /// The watchdog word for `period`, rounded to the nearest tick; a
    /// nonzero period never rounds down to 0 (which would disable it).
    ///
    /// # Errors
    /// [`Error::FieldRange`] above 65535 ticks (about 341 ms).
    pub fn from_period(period: Duration) -> Result<Watchdog> {
        let ns = period.as_nanos();
        let ticks = (ns * Self::TICK_NS_DEN + Self::TICK_NS_NUM / 2) / Self::TICK_NS_NUM;
        let ticks = if ticks == 0 && ns > 0 { 1 } else { ticks };
        let max = field::WATCHDOG_TICKS.max();
        match u16::try_from(ticks) {
            Ok(t) => Ok(Watchdog::default().with_ticks(t)),
            Err(_) => Err(Error::FieldRange {
                field: "watchdog ticks",
                value: u64::try_from(ticks).unwrap_or(u64::MAX),
                max: u64::from(max),
            }),
        }
    }
}

/// A watchdog setting as a person asks for it: a period the WATCHDOG
/// register can hold (one tick, 5.208 us, to 65535 ticks, about 341 ms), or
/// off, which only the word `off` gives. Every front end (flags, web API,
/// configuration files, Python) goes through [`WatchdogSetting::parse`] or
/// [`WatchdogSetting::from_ms`]: a period too short for one tick used to
/// become register value 0, which turns the watchdog off without a word.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum WatchdogSetting {
    /// Off: a host that stops leaves the amplifiers on with the last
    /// command. Say so loudly ([`WatchdogSetting::OFF_WARNING`]).
    Off,
    /// This register word (never 0 ticks).
    Period(Watchdog),
}

/// A watchdog period that the register cannot hold (or is not a number).
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error(
    "watchdog period {} ms is out of range: {}, or `off`",
    crate::human::Number(*asked_ms),
    WatchdogSetting::RANGE
)]
pub struct WatchdogRangeError {
    /// What was asked for, ms.
    pub asked_ms: f64,
}

/// The text given for a watchdog is neither `off` nor a number.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum WatchdogParseError {
    /// Not `off` and not a number.
    #[error("a watchdog is a period in ms or `off`")]
    NotANumber,
    /// A number out of range.
    #[error(transparent)]
    Range(#[from] WatchdogRangeError),
}

impl WatchdogSetting {
    /// The shortest period, ms: one tick (256 / 49.152 MHz).
    pub const MIN_MS: f64 = 256.0 / 49_152.0;
    /// The longest period, ms: 65535 ticks.
    pub const MAX_MS: f64 = 65_535.0 * 256.0 / 49_152.0;
    /// The range in words, with bounds that are themselves accepted.
    pub const RANGE: &'static str =
        "from 0.00521 ms (one firmware tick of 5.208 us) to 341.32 ms (65535 ticks)";
    /// What to print when the watchdog is off.
    pub const OFF_WARNING: &'static str = "WARNING: board watchdogs are OFF: if this host \
        stops, the amplifiers stay enabled with the last command";

    /// A period in milliseconds, rounded to the nearest tick.
    ///
    /// # Errors
    /// Below one tick, above 65535 ticks, or not finite.
    pub fn from_ms(ms: f64) -> core::result::Result<WatchdogSetting, WatchdogRangeError> {
        let err = WatchdogRangeError { asked_ms: ms };
        // (False for NaN.)
        if !(Self::MIN_MS..=Self::MAX_MS).contains(&ms) {
            return Err(err);
        }
        let ticks = (ms / Self::MIN_MS).round();
        if !(1.0..=65_535.0).contains(&ticks) {
            return Err(err);
        }
        Ok(WatchdogSetting::Period(
            Watchdog::default().with_ticks(ticks as u16),
        ))
    }

    /// A period as a duration, rounded to the nearest tick.
    ///
    /// # Errors
    /// Below one tick (zero included: off is [`WatchdogSetting::Off`]),
    /// above 65535 ticks.
    pub fn from_period(
        period: Duration,
    ) -> core::result::Result<WatchdogSetting, WatchdogRangeError> {
        Self::from_ms(period.as_secs_f64() * 1e3)
    }

    /// `off` (any case) or a period in milliseconds.
    ///
    /// # Errors
    /// Not a number, or out of range.
    pub fn parse(text: &str) -> core::result::Result<WatchdogSetting, WatchdogParseError> {
        let t = text.trim();
        if t.eq_ignore_ascii_case("off") {
            return Ok(WatchdogSetting::Off);
        }
        let ms: f64 = t.parse().map_err(|_| WatchdogParseError::NotANumber)?;
        Ok(Self::from_ms(ms)?)
    }

    /// The register word to program (0 ticks only when off).
    pub fn register(self) -> Watchdog {
        match self {
            WatchdogSetting::Off => Watchdog::DISABLED,
            WatchdogSetting::Period(w) => w,
        }
    }

    /// The period, or `None` when off.
    pub fn period(self) -> Option<Duration> {
        match self {
            WatchdogSetting::Off => None,
            WatchdogSetting::Period(w) => Some(w.period()),
        }
    }

    /// The period, zero when off (for arithmetic on waits).
    pub fn period_or_zero(self) -> Duration {
        self.period().unwrap_or(Duration::ZERO)
    }

    /// Whether it is off.
    pub fn is_off(self) -> bool {
        self == WatchdogSetting::Off
    }

    /// The warning to print, or `None` when a period is set.
    pub fn warning(self) -> Option<&'static str> {
        self.is_off().then_some(Self::OFF_WARNING)
    }
}

impl Default for WatchdogSetting {
    /// 20 ms, the dVRK's and the demo's period.
    fn default() -> Self {
        WatchdogSetting::Period(Watchdog::default().with_ticks(3840))
    }
}

impl core::fmt::Display for WatchdogSetting {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            WatchdogSetting::Off => f.write_str("off"),
            WatchdogSetting::Period(w) => {
                let ms = w.period().as_secs_f64() * 1e3;
                write!(f, "{} ms", crate::human::Number((ms * 1e4).round() / 1e4))
            }
        }
    }
}

// ----------------------------------------------------------- HW_VERSION ---

open_enum! {
    /// HW_VERSION: the companion board, a four-character code
    /// (`fpga-board.md` §2).
    pub enum HardwareVersion(u32) {
        /// "QLA1": quad linear amplifier, 4 axes.
        Qla1 = 0x514C_4131,
        /// "DQLA": dual QLA, 8 axes.
        Dqla = 0x4451_4C41,
        /// "dRA1": the dRA1 board.
        Dra1 = 0x6452_4131,
    }
}

impl HardwareVersion {
    /// The four characters of the code (big-endian bytes of the register).
    pub fn fourcc(self) -> [u8; 4] {
        u32::from(self).to_be_bytes()
    }

    /// The code from its four characters.
    pub fn from_fourcc(code: [u8; 4]) -> HardwareVersion {
        HardwareVersion::from(u32::from_be_bytes(code))
    }

    /// The name of a known board ("QLA1", "DQLA", "dRA1"), `"unknown"` otherwise.
    pub fn name(self) -> &'static str {
        match self {
            HardwareVersion::Qla1 => "QLA1",
            HardwareVersion::Dqla => "DQLA",
            HardwareVersion::Dra1 => "dRA1",
            HardwareVersion::Unknown(_) => "unknown",
        }
    }
}

// ----------------------------------------------------------- ETH_STATUS ---

/// The FPGA board generation, told by ETH_STATUS (`fpga-board.md` §2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum FpgaVersion {
    /// FPGA V1: no Ethernet; ETH_STATUS reads 0.
    V1,
    /// FPGA V2: ETH_STATUS bit 31 set.
    V2,
    /// FPGA V3: ETH_STATUS bits 31:30 = 01.
    V3,
}

impl FpgaVersion {
    /// The version number: 1, 2 or 3.
    pub fn number(self) -> u8 {
        match self {
            FpgaVersion::V1 => 1,
            FpgaVersion::V2 => 2,
            FpgaVersion::V3 => 3,
        }
    }

    /// Tell the version from an ETH_STATUS value.
    ///
    /// # Errors
    /// [`Error::InvalidValue`] for a nonzero value with bits 31:30 = 00.
    pub fn from_eth_status(eth_status: u32) -> Result<FpgaVersion> {
        if eth_status == 0 {
            Ok(FpgaVersion::V1)
        } else if field::ETH_V2.extract(eth_status) == 1 {
            Ok(FpgaVersion::V2)
        } else if field::ETH_VERSION_BITS.extract(eth_status) == 0b01 {
            Ok(FpgaVersion::V3)
        } else {
            Err(Error::InvalidValue {
                what: "ETH_STATUS FPGA version bits",
                value: eth_status,
            })
        }
    }

    /// The version bits of ETH_STATUS for this version (other status bits
    /// zero): 0, `0x8000_0000` or `0x4000_0000`.
    pub fn eth_status_bits(self) -> u32 {
        let f = field::ETH_VERSION_BITS;
        match self {
            FpgaVersion::V1 => 0,
            FpgaVersion::V2 => f.insert(0, 0b10),
            FpgaVersion::V3 => f.insert(0, 0b01),
        }
    }

    /// Whether the board has Ethernet (V2 and V3).
    pub fn has_ethernet(self) -> bool {
        self != FpgaVersion::V1
    }
}

// -------------------------------------------------------------- IP_ADDR ---

/// The IP_ADDR word of an IPv4 address: written little-endian
/// (`fpga-board.md` §2: 169.254.0.100 -> `0x6400FEA9`).
pub fn ip_to_register(ip: Ipv4Addr) -> u32 {
    u32::from_le_bytes(ip.octets())
}

/// The IPv4 address of an IP_ADDR word (`fpga-board.md` §2).
pub fn ip_from_register(word: u32) -> Ipv4Addr {
    Ipv4Addr::from(word.to_le_bytes())
}

// --------------------------------------------------- TEMPERATURE, GIT ---

quadlet_register! {
    /// TEMPERATURE: two 8-bit amplifier temperatures (`fpga-board.md` §2).
    pub struct Temperature {
        /// The temperature in bits 15:8.
        upper, set_upper, with_upper: u8 = field::TEMPERATURE_UPPER;
        /// The temperature in bits 7:0.
        lower, set_lower, with_lower: u8 = field::TEMPERATURE_LOWER;
    }
}

quadlet_register! {
    /// GIT_DESC: the firmware's source version (`fpga-board.md` §2).
    pub struct GitDesc {
        /// Short commit id, bits 31:4 (28 bits, seven hex digits).
        commit, set_commit, with_commit: u32 = field::GIT_COMMIT;
        /// The build had uncommitted changes, bit 3.
        dirty, set_dirty, with_dirty: bool = field::GIT_DIRTY;
    }
}

// ------------------------------------------------------ DIGITAL I/O ---

quadlet_register! {
    /// DIGITAL_IN (`fpga-board.md` §2): 4-bit masks, bit i = axis i + 1.
    pub struct DigitalIn {
        /// Motor supply voltage fault, bit 31.
        v_fault, set_v_fault, with_v_fault: bool = field::DIN_V_FAULT;
        /// The waveform table drives outputs (register 6 bit 31), bit 29
        /// (`fpga-board-extras.md` §3).
        waveform_active, set_waveform_active, with_waveform_active: bool = field::DIN_WAVEFORM;
        /// Motor-supply comparator, bit 28: 1 = the axis 4 DAC voltage is
        /// below the motor supply (`fpga-board-extras.md` §7).
        supply_comparator, set_supply_comparator, with_supply_comparator: bool =
            field::DIN_SUPPLY_COMPARATOR;
        /// Encoder A lines, bits 27:24.
        enc_a, set_enc_a, with_enc_a: u8 = field::DIN_ENC_A;
        /// Encoder B lines, bits 23:20.
        enc_b, set_enc_b, with_enc_b: u8 = field::DIN_ENC_B;
        /// Encoder index lines, bits 19:16.
        index, set_index, with_index: u8 = field::DIN_INDEX;
        /// Digital outputs as stored (raw, not inverted), bits 15:12.
        outputs, set_outputs, with_outputs: u8 = field::DIN_OUTPUTS;
        /// Negative limit switches, bits 11:8.
        neg_limits, set_neg_limits, with_neg_limits: u8 = field::DIN_NEG_LIMITS;
        /// Positive limit switches, bits 7:4.
        pos_limits, set_pos_limits, with_pos_limits: u8 = field::DIN_POS_LIMITS;
        /// Home switches, bits 3:0.
        home, set_home, with_home: u8 = field::DIN_HOME;
    }
}

/// A DIGITAL_OUT write (register 6, `fpga-board-extras.md` §3): bits 11:8
/// the outputs to change, bits 3:0 their new values *as stored* (the
/// firmware keeps exactly the bits written), bit 31 play the waveform table
/// on the masked outputs. Output pins invert the stored value, so the
/// reference host writes the complement of the levels it means
/// ([`levels`](Self::levels)): raw 1 = output low.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct DigitalOutWrite {
    /// Outputs to change (bit i = DOUT i+1), 4 bits.
    pub mask: u8,
    /// Their stored (raw) values, 4 bits; bits outside `mask` are ignored
    /// by the board.
    pub raw: u8,
    /// Play the waveform table on the masked outputs (bit 31).
    pub play_waveform: bool,
}

impl DigitalOutWrite {
    /// Decode the written word; bits outside the encoding are ignored.
    pub fn parse(word: u32) -> DigitalOutWrite {
        DigitalOutWrite {
            mask: field::DOUT_MASK.extract(word) as u8,
            raw: field::DOUT_RAW.extract(word) as u8,
            play_waveform: field::DOUT_PLAY.extract(word) != 0,
        }
    }

    /// Encode as the written word (mask and values cut to 4 bits).
    pub fn to_word(self) -> u32 {
        let w = field::DOUT_MASK.insert(0, u32::from(self.mask));
        let w = field::DOUT_RAW.insert(w, u32::from(self.raw));
        field::DOUT_PLAY.insert(w, u32::from(self.play_waveform))
    }

    /// Set the masked outputs to `levels` as the reference host means them
    /// (`WriteDigitalOutput`): it sends `mask<<8 | (~levels & mask)`.
    pub fn levels(mask: u8, levels: u8) -> DigitalOutWrite {
        DigitalOutWrite {
            mask: mask & 0xF,
            raw: !levels & mask & 0xF,
            play_waveform: false,
        }
    }

    /// Start the waveform table on the masked outputs, leaving them at
    /// `levels` when it stops (`WriteWaveformControl`: `0x80000000 |
    /// mask<<8 | (~levels & mask)`; a zero mask sends no bit 31, which
    /// stops playback).
    pub fn waveform(mask: u8, levels: u8) -> DigitalOutWrite {
        DigitalOutWrite {
            play_waveform: mask & 0xF != 0,
            ..DigitalOutWrite::levels(mask, levels)
        }
    }

    /// The levels the masked outputs are set to, as the host means them.
    pub fn output_levels(self) -> u8 {
        !self.raw & self.mask & 0xF
    }
}

quadlet_register! {
    /// DIGITAL_OUT as read (register 6, `fpga-board-extras.md` §3).
    pub struct DigitalOutRead {
        /// The waveform table drives at least one output, bit 31.
        table_active, set_table_active, with_table_active: bool = field::DOUT_TABLE_ACTIVE;
        /// Same, and the current entry is valid, bit 30.
        table_valid, set_table_valid, with_table_valid: bool = field::DOUT_TABLE_VALID;
        /// Current table index, bits 25:16.
        table_index, set_table_index, with_table_index: u16 = field::DOUT_TABLE_INDEX;
        /// Extra I/O, bits 11:8 (FPGA V3.1 only, else 0).
        extra_io, set_extra_io, with_extra_io: u8 = field::DOUT_EXTRA_IO;
        /// The outputs as stored (raw), bits 3:0.
        outputs, set_outputs, with_outputs: u8 = field::DOUT_RAW;
    }
}

quadlet_register! {
    /// DOUT_CTRL (axis offset 8, `fpga-board-extras.md` §3): how long the
    /// raw output stays 1 and 0, in 49.152 MHz clocks; 0 = forever. Both
    /// non-zero: PWM; one non-zero: one-shot.
    pub struct DoutCtrl {
        /// Clocks the raw output stays 1, bits 31:16.
        high_time, set_high_time, with_high_time: u16 = field::DOUT_CTRL_HIGH;
        /// Clocks the raw output stays 0, bits 15:0.
        low_time, set_low_time, with_low_time: u16 = field::DOUT_CTRL_LOW;
    }
}

quadlet_register! {
    /// One entry of the digital-output waveform table (space 8,
    /// `fpga-board-extras.md` §3). The entry lasts `end_count + 1` clocks;
    /// playback stops at the first entry without the valid bit.
    pub struct WaveformEntry {
        /// Valid (playback continues), bit 31.
        valid, set_valid, with_valid: bool = field::WAVE_VALID;
        /// End count, bits 30:8 (`0x7FFFFF` = 170.7 ms).
        end_count, set_end_count, with_end_count: u32 = field::WAVE_END_COUNT;
        /// Raw output values (bit i -> DOUT i+1), bits 7:0.
        outputs, set_outputs, with_outputs: u8 = field::WAVE_OUTPUTS;
    }
}

impl WaveformEntry {
    /// Clocks the entry lasts: `end_count + 1`.
    pub fn clocks(self) -> u64 {
        u64::from(self.end_count()) + 1
    }
}

// ------------------------------------------------------------------ ADC ---

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

    #[test]
    fn phy_ctrl_and_data() {
        let w = PhyRequest::Write {
            register: 1,
            data: 0x3F,
        };
        assert_eq!(w.to_word(), Ok(0x113F));
        assert_eq!(PhyRequest::parse(0x113F), Ok(w));
        let r = PhyRequest::Read { register: 1 };
        assert_eq!(r.to_word(), Ok(1));
        assert_eq!(PhyRequest::parse(0), Ok(PhyRequest::Read { register: 0 }));
        assert!(PhyRequest::parse(0x0100).is_err());
        assert!(PhyRequest::parse(0x2000).is_err());
        assert!(PhyRequest::Read { register: 16 }.to_word().is_err());
        let d = PhyData(0x0000_013F);
        assert_eq!((d.register(), d.data()), (1, 0x3F));
        assert_eq!(PhyData::default().with_register(1).with_data(0x3F), d);
    }

    #[test]
    fn watchdog_settings_refuse_what_the_register_cannot_hold() {
        use std::string::ToString;
        // Under one tick used to become 0 ticks: the watchdog off.
        for ms in [
            1e-7,
            1e-9,
            0.0,
            -5.0,
            0.005,
            f64::NAN,
            f64::INFINITY,
            341.4,
            1e300,
        ] {
            let e = WatchdogSetting::from_ms(ms).unwrap_err();
            assert!(e.to_string().contains("out of range"), "{e}");
        }
        assert!(
            WatchdogSetting::from_ms(1e300)
                .unwrap_err()
                .to_string()
                .contains("1e300 ms")
        );
        assert!(WatchdogSetting::from_period(Duration::ZERO).is_err());
        assert!(WatchdogSetting::from_period(Duration::from_nanos(5000)).is_err());
        // The bounds the message shows are accepted.
        assert!(WatchdogSetting::from_ms(0.00521).is_ok());
        assert!(WatchdogSetting::from_ms(341.32).is_ok());
        let one = WatchdogSetting::from_ms(WatchdogSetting::MIN_MS).unwrap();
        assert_eq!(one.register().ticks(), 1);
        let max = WatchdogSetting::from_ms(WatchdogSetting::MAX_MS).unwrap();
        assert_eq!(max.register().ticks(), 0xFFFF);
        let twenty = WatchdogSetting::parse(" 20 ").unwrap();
        assert_eq!(twenty, WatchdogSetting::default());
        assert_eq!(twenty.to_string(), "20 ms");
        assert_eq!(twenty.register().ticks(), 3840);
        assert_eq!(WatchdogSetting::parse("OFF").unwrap(), WatchdogSetting::Off);
        assert!(WatchdogSetting::Off.warning().is_some());
        assert_eq!(WatchdogSetting::Off.register(), Watchdog::DISABLED);
        assert!(WatchdogSetting::parse("zero").is_err());
        assert!(WatchdogSetting::parse("0").is_err());
    }

    #[test]
    fn watchdog_ticks() {
        assert_eq!(Watchdog::POWER_UP.ticks(), 0x1680);
        assert_eq!(Watchdog::POWER_UP.period(), Duration::from_millis(30));
        assert_eq!(
            Watchdog::from_period(Duration::from_millis(30)),
            Ok(Watchdog::POWER_UP)
        );
        assert_eq!(Watchdog(1).period(), Duration::from_nanos(5208));
        assert_eq!(
            Watchdog::from_period(Duration::ZERO),
            Ok(Watchdog::DISABLED)
        );
        assert!(Watchdog::DISABLED.is_disabled());
        assert_eq!(
            Watchdog::from_period(Duration::from_nanos(1)),
            Ok(Watchdog(1))
        );
        let max = Watchdog(0xFFFF).period();
        assert_eq!(Watchdog::from_period(max), Ok(Watchdog(0xFFFF)));
        assert!(Watchdog::from_period(Duration::from_millis(342)).is_err());
        assert!(Watchdog::from_period(Duration::MAX).is_err());
    }

    #[test]
    fn hardware_versions() {
        assert_eq!(HardwareVersion::from(0x514C_4131), HardwareVersion::Qla1);
        assert_eq!(&HardwareVersion::Qla1.fourcc(), b"QLA1");
        assert_eq!(&HardwareVersion::Dqla.fourcc(), b"DQLA");
        assert_eq!(&HardwareVersion::Dra1.fourcc(), b"dRA1");
        assert_eq!(
            HardwareVersion::from_fourcc(*b"DQLA"),
            HardwareVersion::Dqla
        );
        assert_eq!(HardwareVersion::Dra1.name(), "dRA1");
        assert_eq!(HardwareVersion::from(7).name(), "unknown");
    }

    #[test]
    fn fpga_versions() {
        assert_eq!(FpgaVersion::from_eth_status(0), Ok(FpgaVersion::V1));
        assert_eq!(
            FpgaVersion::from_eth_status(0x8000_1234),
            Ok(FpgaVersion::V2)
        );
        assert_eq!(
            FpgaVersion::from_eth_status(0xC000_0000),
            Ok(FpgaVersion::V2)
        );
        assert_eq!(
            FpgaVersion::from_eth_status(0x4000_0001),
            Ok(FpgaVersion::V3)
        );
        assert!(FpgaVersion::from_eth_status(0x0000_0001).is_err());
        for v in [FpgaVersion::V1, FpgaVersion::V2, FpgaVersion::V3] {
            assert_eq!(FpgaVersion::from_eth_status(v.eth_status_bits()), Ok(v));
        }
        assert!(!FpgaVersion::V1.has_ethernet() && FpgaVersion::V3.has_ethernet());
    }

    #[test]
    fn ip_addr_is_little_endian() {
        let ip = Ipv4Addr::new(169, 254, 0, 100);
        assert_eq!(ip_to_register(ip), 0x6400_FEA9);
        assert_eq!(ip_from_register(0x6400_FEA9), ip);
    }

    #[test]
    fn digital_out_stores_raw_bits() {
        // The host's WriteDigitalOutput(0xF, levels 0b0101) sends the
        // complement; the board stores it as written.
        let w = DigitalOutWrite::levels(0x0F, 0b0101);
        assert_eq!(w.to_word(), 0x0F0A);
        assert_eq!(DigitalOutWrite::parse(0x0F0A), w);
        assert_eq!(w.raw, 0xA);
        assert_eq!(w.output_levels(), 0b0101);
        // Issue 13: writing 0x0F0E stores 0xE.
        assert_eq!(DigitalOutWrite::parse(0x0F0E).raw, 0xE);
        // Outputs outside the mask are not sent.
        assert_eq!(DigitalOutWrite::levels(0x01, 0xFF).to_word(), 0x0100);
        // WriteWaveformControl(0x03, 0x03).
        assert_eq!(DigitalOutWrite::waveform(0x3, 0x3).to_word(), 0x8000_0300);
        assert_eq!(DigitalOutWrite::waveform(0, 0xF).to_word(), 0);
        let r = DigitalOutRead::default()
            .with_table_active(true)
            .with_table_index(0x3FF)
            .with_outputs(0xE);
        assert_eq!(r.raw(), 0x83FF_000E);
        let e = WaveformEntry(0x80C0_0003);
        assert!(e.valid());
        assert_eq!(e.clocks(), 0xC000 + 1);
        assert_eq!(e.outputs(), 3);
        assert_eq!(DoutCtrl(0x0001_0002).high_time(), 1);
    }

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

    #[test]
    fn small_words() {
        let d = DigitalIn::default()
            .with_v_fault(true)
            .with_enc_a(1)
            .with_enc_b(2)
            .with_index(3)
            .with_outputs(4)
            .with_neg_limits(5)
            .with_pos_limits(6)
            .with_home(7);
        assert_eq!(d.raw(), 0x8123_4567);
        let t = Temperature::default().with_upper(40).with_lower(41);
        assert_eq!(t.raw(), 0x2829);
        let g = GitDesc::default().with_commit(0x0ab_cdef).with_dirty(true);
        assert_eq!(g.raw(), 0x0ABC_DEF8);
        let a = AdcWord(0x1234_5678);
        assert_eq!((a.pot(), a.current()), (0x1234, 0x5678));
        assert_eq!(u32::from(a), 0x1234_5678);
        assert_eq!(AdcWord::from(7), AdcWord(7));
    }
}
