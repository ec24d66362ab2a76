//! The Snake node's register quadlets, raw bits only.
//!
//! STATUS follows Table 2 of seed 001 bit for bit. The other layouts are
//! Firelink's (the seed does not draw them); each is defined once in the
//! private `field` module. The PHY control/data registers and the
//! watchdog period use the JHU board's encodings:
//! [`PhyRequest`](crate::qla::registers::PhyRequest),
//! [`PhyData`](crate::qla::registers::PhyData) and
//! [`Watchdog`](crate::qla::registers::Watchdog) (16 bits of 256
//! system clocks, 5.2083 us; 0 = off).
//!
//! Conventions the host library turns into the seed's API values
//! (§7.2): the ADC reports signed 14-bit values around 1.25 V
//! ([`AdcData`]; the API adds 8192); the DAC takes unsigned 16-bit codes
//! whose midpoint is 0 V at the motor ([`DAC_MIDPOINT`]); the encoder
//! count is an unsigned 24-bit counter that should be preloaded with
//! [`ENCODER_MIDPOINT`]; the encoder period is a signed count of
//! 768 kHz ticks.
//!
//! ```
//! use firelink_wire::snake::registers::{AdcData, PotCommand, SnakeStatus};
//! let s = SnakeStatus::default().with_board_id(5).with_amp_enable(0b101).with_faults(0b10);
//! assert_eq!(s.raw(), 0x0502_0005);
//! let adc = AdcData::from_signed(-8192, 8191);
//! assert_eq!((adc.pot_api(), adc.current_api()), (0, 16383));
//! assert!(PotCommand::parse(0x3E00_0000).is_err()); // EEPROM word 14 does not exist
//! ```

use crate::error::{Error, Result};
use crate::open_enum::open_enum;
use crate::qla::{check_max, quadlet_register};
use crate::snake::{CHANNELS, EEPROM_WORDS, WIPER_MAX, check_channel};

/// Bit fields of the registers, each defined once.
mod field {
    use crate::field::Field;

    // STATUS (Table 2).
    pub const STATUS_UNUSED: Field = Field::new(0, 31, 28);
    pub const STATUS_BOARD_ID: Field = Field::new(0, 27, 24);
    pub const STATUS_WATCHDOG_TIMEOUT: Field = Field::new(0, 23, 23);
    pub const STATUS_FAULTS: Field = Field::new(0, 22, 16);
    pub const STATUS_ENABLE_MASK: Field = Field::new(0, 15, 8);
    pub const STATUS_AMP_ENABLE: Field = Field::new(0, 7, 0);

    // Power control (STATUS written): the same mask and enable fields.
    pub const POWER_MASK: Field = Field::new(0, 15, 8);
    pub const POWER_ENABLE: Field = Field::new(0, 7, 0);

    // ADC data: two 14-bit two's-complement samples.
    pub const ADC_POT: Field = Field::new(0, 29, 16);
    pub const ADC_CURRENT: Field = Field::new(0, 13, 0);

    // DAC control as written: which DAC channel, and its code.
    pub const DAC_WRITE_RESERVED: Field = Field::new(0, 31, 17);
    pub const DAC_WRITE_LIMIT: Field = Field::new(0, 16, 16);
    pub const DAC_WRITE_VALUE: Field = Field::new(0, 15, 0);
    // DAC control as read: both codes.
    pub const DAC_READ_LIMIT: Field = Field::new(0, 31, 16);
    pub const DAC_READ_VOLTAGE: Field = Field::new(0, 15, 0);

    // Digital potentiometer command.
    pub const POT_OP: Field = Field::new(0, 31, 28);
    pub const POT_ADDRESS: Field = Field::new(0, 27, 24);
    pub const POT_RESERVED: Field = Field::new(0, 23, 16);
    pub const POT_DATA: Field = Field::new(0, 15, 0);
    // Digital potentiometer result.
    pub const RESULT_READY: Field = Field::new(0, 31, 31);
    pub const RESULT_BUSY: Field = Field::new(0, 30, 30);
    pub const RESULT_ERROR: Field = Field::new(0, 29, 29);
    pub const RESULT_OP: Field = Field::new(0, 27, 24);
    pub const RESULT_ADDRESS: Field = Field::new(0, 23, 20);
    pub const RESULT_DATA: Field = Field::new(0, 15, 0);

    // Encoder.
    pub const ENC_OVERFLOW: Field = Field::new(0, 24, 24);
    pub const ENC_COUNT: Field = Field::new(0, 23, 0);
    pub const ENC_PRELOAD: Field = Field::new(0, 23, 0);
    pub const ENC_PRELOAD_RESERVED: Field = Field::new(0, 31, 24);
    pub const ENC_PERIOD: Field = Field::new(0, 15, 0);

    // Block write: one quadlet per channel.
    pub const COMMAND_VALID: Field = Field::new(0, 31, 31);
    pub const COMMAND_RESERVED: Field = Field::new(0, 30, 16);
    pub const COMMAND_VALUE: Field = Field::new(0, 15, 0);
}

/// The DAC code of the midpoint, 1.25 V: zero volts across the motor
/// (§7.2: the command is a signed value centred on this code).
pub const DAC_MIDPOINT: u16 = 0x8000;
/// The encoder preload the seed recommends: the middle of the 24-bit
/// range, so the count can go either way without overflowing (§7.2).
pub const ENCODER_MIDPOINT: u32 = 0x80_0000;
/// Largest encoder count (24 bits).
pub const ENCODER_MAX: u32 = 0xFF_FFFF;
/// The ADC's full scale, volts (0 to 2.5 V, reported around 1.25 V).
pub const ADC_FULL_SCALE_VOLTS: f64 = 2.5;
/// What the API adds to a signed ADC sample (§7.2).
pub const ADC_API_OFFSET: i32 = 8192;
/// The DAC's full scale, volts.
pub const DAC_FULL_SCALE_VOLTS: f64 = 2.5;
/// The encoder period clock: 49.152 MHz / 64 = 768 kHz (§7.2).
pub const PERIOD_CLOCK_HZ: u32 = 768_000;
/// The version register's top 24 bits on Firelink's emulated firmware:
/// "SNK". The low byte is the revision. (The seed sets the register at
/// synthesis and deprecated it; a host uses it to tell a Snake node from
/// other boards on the bus.)
pub const VERSION_SIGNATURE: u32 = 0x53_4E4B;
/// The version register of the emulated firmware: "SNK", revision 2 (the
/// seed's final revision, §5.4).
pub const VERSION: u32 = (VERSION_SIGNATURE << 8) | 2;

/// Whether a version register value is a Snake node's.
pub fn is_snake_version(word: u32) -> bool {
    word >> 8 == VERSION_SIGNATURE
}

// ---------------------------------------------------------------- STATUS ---

quadlet_register! {
    /// STATUS (Table 2). Bit `c - 1` of the 7- and 8-bit fields is
    /// channel `c`; bit 7 of the mask and enable fields is unused.
    pub struct SnakeStatus {
        /// Bits 31:28, unused (0).
        unused, set_unused, with_unused: u8 = field::STATUS_UNUSED;
        /// Board ID from the rotary switch, bits 27:24.
        board_id, set_board_id, with_board_id: u8 = field::STATUS_BOARD_ID;
        /// The watchdog timed out, bit 23 (all amplifiers were disabled).
        watchdog_timeout, set_watchdog_timeout, with_watchdog_timeout: bool =
            field::STATUS_WATCHDOG_TIMEOUT;
        /// Amplifier status (fault) flags, bits 22:16, one per channel.
        faults, set_faults, with_faults: u8 = field::STATUS_FAULTS;
        /// The enable mask of the last power-control write, bits 15:8.
        enable_mask, set_enable_mask, with_enable_mask: u8 = field::STATUS_ENABLE_MASK;
        /// Amplifier enables, bits 7:0, one per channel.
        amp_enable, set_amp_enable, with_amp_enable: u8 = field::STATUS_AMP_ENABLE;
    }
}

impl SnakeStatus {
    /// Whether channel `channel` (1..=7) has its amplifier enabled.
    pub fn amp_enabled(self, channel: u8) -> bool {
        channel_bit(channel).is_some_and(|b| self.amp_enable() & b != 0)
    }

    /// Whether channel `channel` (1..=7) reports an amplifier fault.
    pub fn fault(self, channel: u8) -> bool {
        channel_bit(channel).is_some_and(|b| self.faults() & b != 0)
    }
}

/// Bit of channel `channel` (1..=7) in the per-channel fields.
fn channel_bit(channel: u8) -> Option<u8> {
    check_channel(channel).ok().map(|c| 1 << (c - 1))
}

/// Mask of every channel in the per-channel fields.
pub const ALL_CHANNELS: u8 = (1 << CHANNELS) - 1;

quadlet_register! {
    /// Power control, what a STATUS write carries (`SetPowerControl`):
    /// the amplifiers whose bit is set in the mask take the matching
    /// enable bit; the others keep theirs. Other bits are ignored.
    pub struct PowerControl {
        /// Which amplifiers to change, bits 15:8.
        mask, set_mask, with_mask: u8 = field::POWER_MASK;
        /// Their new enables, bits 7:0.
        enable, set_enable, with_enable: u8 = field::POWER_ENABLE;
    }
}

impl PowerControl {
    /// Every amplifier on (`true`) or off.
    pub fn all(on: bool) -> PowerControl {
        PowerControl::default()
            .with_mask(ALL_CHANNELS)
            .with_enable(if on { ALL_CHANNELS } else { 0 })
    }

    /// One channel's amplifier on or off.
    ///
    /// # Errors
    /// [`Error::OutOfRange`] for a channel outside 1..=7.
    pub fn channel(channel: u8, on: bool) -> Result<PowerControl> {
        let bit = 1u8 << (check_channel(channel)? - 1);
        Ok(PowerControl::default()
            .with_mask(bit)
            .with_enable(if on { bit } else { 0 }))
    }

    /// The enables after applying this write to `current` (bit 7, which
    /// no channel has, stays 0).
    pub fn apply(self, current: u8) -> u8 {
        ((current & !self.mask()) | (self.enable() & self.mask())) & ALL_CHANNELS
    }
}

// ------------------------------------------------------------------- ADC ---

quadlet_register! {
    /// ADC data: the potentiometer (bits 29:16) and the motor current
    /// (bits 13:0), each a 14-bit two's-complement sample of 0..2.5 V
    /// taken around 1.25 V (-8192..=8191). Bits 31:30 and 15:14 are 0.
    pub struct AdcData {
        /// Raw 14-bit potentiometer field.
        pot_bits, set_pot_bits, with_pot_bits: u16 = field::ADC_POT;
        /// Raw 14-bit motor-current field.
        current_bits, set_current_bits, with_current_bits: u16 = field::ADC_CURRENT;
    }
}

/// Sign-extend a 14-bit field.
fn signed14(bits: u16) -> i16 {
    ((bits << 2) as i16) >> 2
}

/// The 14-bit field of a signed sample, saturated to -8192..=8191.
fn bits14(sample: i16) -> u16 {
    (sample.clamp(-8192, 8191) as u16) & 0x3FFF
}

impl AdcData {
    /// Both samples, signed; each saturates to -8192..=8191.
    pub fn from_signed(pot: i16, current: i16) -> AdcData {
        AdcData::default()
            .with_pot_bits(bits14(pot))
            .with_current_bits(bits14(current))
    }

    /// The potentiometer sample, signed around 1.25 V.
    pub fn pot(self) -> i16 {
        signed14(self.pot_bits())
    }

    /// The motor-current sample, signed around 1.25 V.
    pub fn current(self) -> i16 {
        signed14(self.current_bits())
    }

    /// The potentiometer as the API reports it: sample + 8192, 0..=16383.
    pub fn pot_api(self) -> u16 {
        adc_to_api(self.pot())
    }

    /// The motor current as the API reports it: sample + 8192, 0..=16383.
    pub fn current_api(self) -> u16 {
        adc_to_api(self.current())
    }
}

/// The API value of a signed ADC sample: `sample + 8192` (§7.2), so
/// 0..=16383 for 0..2.5 V.
pub fn adc_to_api(sample: i16) -> u16 {
    (i32::from(sample).clamp(-8192, 8191) + ADC_API_OFFSET) as u16
}

/// The signed sample of an API value (`api - 8192`).
///
/// # Errors
/// [`Error::FieldRange`] above 16383.
pub fn api_to_adc(api: u16) -> Result<i16> {
    check_max("ADC API value", u64::from(api), 16383)?;
    Ok((i32::from(api) - ADC_API_OFFSET) as i16)
}

/// Volts at the ADC input of an API value (0..2.5 V).
pub fn adc_api_to_volts(api: u16) -> f64 {
    f64::from(api.min(16383)) * ADC_FULL_SCALE_VOLTS / 16384.0
}

/// Volts at the DAC output of a code (0..2.5 V).
pub fn dac_to_volts(code: u16) -> f64 {
    f64::from(code) * DAC_FULL_SCALE_VOLTS / 65536.0
}

// ------------------------------------------------------------------- DAC ---

/// A DAC control write: the dual DAC takes one channel per transaction
/// (§6.2): bit 16 selects the current limit (1) or the motor voltage (0),
/// bits 15:0 carry the code; bits 31:17 must be 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DacCommand {
    /// DAC channel A: the motor command (a voltage in speed mode, a
    /// torque in torque mode), [`DAC_MIDPOINT`] = 0.
    MotorVoltage(u16),
    /// DAC channel B: the motor current limit, 0 = none allowed.
    CurrentLimit(u16),
}

impl DacCommand {
    /// Decode a DAC control write.
    ///
    /// # Errors
    /// [`Error::InvalidValue`] when a reserved bit is set.
    pub fn parse(word: u32) -> Result<DacCommand> {
        if field::DAC_WRITE_RESERVED.extract(word) != 0 {
            return Err(Error::InvalidValue {
                what: "Snake DAC control word (bits 31:17 must be 0)",
                value: word,
            });
        }
        let value = field::DAC_WRITE_VALUE.extract(word) as u16;
        Ok(if field::DAC_WRITE_LIMIT.extract(word) == 1 {
            DacCommand::CurrentLimit(value)
        } else {
            DacCommand::MotorVoltage(value)
        })
    }

    /// The DAC control word.
    pub fn to_word(self) -> u32 {
        let (limit, value) = match self {
            DacCommand::MotorVoltage(v) => (0, v),
            DacCommand::CurrentLimit(v) => (1, v),
        };
        field::DAC_WRITE_VALUE.insert(field::DAC_WRITE_LIMIT.insert(0, limit), u32::from(value))
    }
}

quadlet_register! {
    /// The DAC control register as read: both codes last written.
    pub struct DacReadback {
        /// Current limit code, bits 31:16.
        current_limit, set_current_limit, with_current_limit: u16 = field::DAC_READ_LIMIT;
        /// Motor command code, bits 15:0.
        motor_voltage, set_motor_voltage, with_motor_voltage: u16 = field::DAC_READ_VOLTAGE;
    }
}

// ------------------------------------------------- digital potentiometer ---

/// A digital-potentiometer wiper position, 0..=1023 (10 bits): 0 puts
/// the wiper at terminal A, 1023 at terminal B.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
pub struct Wiper(u16);

impl Wiper {
    /// The seed's suggested starting value for the Snake robot's motors
    /// (feedback gain about 2, §7.2).
    pub const NOMINAL: Wiper = Wiper(375);

    /// A wiper position.
    ///
    /// # Errors
    /// [`Error::FieldRange`] above 1023.
    pub fn new(value: u16) -> Result<Wiper> {
        check_max("digital pot wiper", u64::from(value), u64::from(WIPER_MAX))?;
        Ok(Wiper(value))
    }

    /// The position.
    pub fn value(self) -> u16 {
        self.0
    }

    /// The motor-current feedback gain it sets, eq. 1 of seed 001:
    /// `G = (12.1 + 10 w/1023) / (1.5 + 10 (1023 - w)/1023)` (ohms; the
    /// 10 ohm is the pot's nominal resistance).
    pub fn feedback_gain(self) -> f64 {
        let w = f64::from(self.0) / f64::from(WIPER_MAX);
        (12.1 + 10.0 * w) / (1.5 + 10.0 * (1.0 - w))
    }
}

/// The pot's two digital outputs (§5.2): O1 selects the control mode
/// (low: torque, high: speed); O2 is free.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct PotOutputs {
    /// O1: `true` selects speed control, `false` torque control.
    pub speed_mode: bool,
    /// O2: the spare output.
    pub o2: bool,
}

impl PotOutputs {
    /// From the two low bits (bit 0 = O1, bit 1 = O2).
    ///
    /// # Errors
    /// [`Error::FieldRange`] above 3.
    pub fn from_bits(bits: u16) -> Result<PotOutputs> {
        check_max("digital pot outputs", u64::from(bits), 3)?;
        Ok(PotOutputs {
            speed_mode: bits & 1 != 0,
            o2: bits & 2 != 0,
        })
    }

    /// The two bits (bit 0 = O1, bit 1 = O2).
    pub fn bits(self) -> u16 {
        u16::from(self.speed_mode) | (u16::from(self.o2) << 1)
    }
}

open_enum! {
    /// The operation field of a digital-potentiometer command (bits 31:28).
    pub enum PotOp(u8) {
        /// Do nothing.
        Nop = 0,
        /// Read the wiper into the data register.
        ReadWiper = 1,
        /// Set the wiper.
        WriteWiper = 2,
        /// Read one EEPROM word.
        ReadEeprom = 3,
        /// Write one EEPROM word (refused while write-protected).
        WriteEeprom = 4,
        /// Read the two digital outputs.
        ReadOutputs = 5,
        /// Set the two digital outputs.
        WriteOutputs = 6,
        /// Read the EEPROM write protection.
        ReadWriteProtect = 7,
        /// Set or clear the EEPROM write protection.
        WriteWriteProtect = 8,
    }
}

/// A digital-potentiometer command, written to the channel's pot control
/// register. The FPGA runs it over SPI (pausing the channel's ADC or DAC
/// while it does, §6.2) and leaves the result in the pot data register
/// ([`PotResult`]). Layout: op in bits 31:28, EEPROM word in 27:24,
/// data in 15:0; bits 23:16 must be 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PotCommand {
    /// Read the wiper.
    ReadWiper,
    /// Set the wiper.
    WriteWiper(Wiper),
    /// Read EEPROM word 0..=13.
    ReadEeprom(u8),
    /// Write EEPROM word 0..=13.
    WriteEeprom {
        /// The word, 0..=13.
        word: u8,
        /// Its new value.
        value: u16,
    },
    /// Read the digital outputs.
    ReadOutputs,
    /// Set the digital outputs.
    WriteOutputs(PotOutputs),
    /// Read the write protection.
    ReadWriteProtect,
    /// Set (`true`) or clear the write protection.
    WriteProtect(bool),
}

/// Check an EEPROM word index.
///
/// # Errors
/// [`Error::OutOfRange`] above 13.
pub fn check_eeprom_word(word: u8) -> Result<u8> {
    if usize::from(word) < EEPROM_WORDS {
        Ok(word)
    } else {
        Err(Error::OutOfRange {
            what: "EEPROM word",
            value: i64::from(word),
            min: 0,
            max: EEPROM_WORDS as i64 - 1,
        })
    }
}

impl PotCommand {
    /// Decode a pot control write.
    ///
    /// # Errors
    /// [`Error::InvalidValue`] for a NOP, an unknown operation or reserved
    /// bits set; the errors of [`Wiper::new`], [`check_eeprom_word`] and
    /// [`PotOutputs::from_bits`] for values out of range.
    pub fn parse(word: u32) -> Result<PotCommand> {
        let bad = Error::InvalidValue {
            what: "Snake digital pot command",
            value: word,
        };
        if field::POT_RESERVED.extract(word) != 0 {
            return Err(bad);
        }
        let op = PotOp::from(field::POT_OP.extract(word) as u8);
        let address = field::POT_ADDRESS.extract(word) as u8;
        let data = field::POT_DATA.extract(word) as u16;
        let no_operand = address == 0 && data == 0;
        let command = match op {
            PotOp::ReadWiper if no_operand => PotCommand::ReadWiper,
            PotOp::WriteWiper if address == 0 => PotCommand::WriteWiper(Wiper::new(data)?),
            PotOp::ReadEeprom if data == 0 => PotCommand::ReadEeprom(check_eeprom_word(address)?),
            PotOp::WriteEeprom => PotCommand::WriteEeprom {
                word: check_eeprom_word(address)?,
                value: data,
            },
            PotOp::ReadOutputs if no_operand => PotCommand::ReadOutputs,
            PotOp::WriteOutputs if address == 0 => {
                PotCommand::WriteOutputs(PotOutputs::from_bits(data)?)
            }
            PotOp::ReadWriteProtect if no_operand => PotCommand::ReadWriteProtect,
            PotOp::WriteWriteProtect if address == 0 && data <= 1 => {
                PotCommand::WriteProtect(data == 1)
            }
            _ => return Err(bad),
        };
        Ok(command)
    }

    /// The operation code.
    pub fn op(self) -> PotOp {
        match self {
            PotCommand::ReadWiper => PotOp::ReadWiper,
            PotCommand::WriteWiper(_) => PotOp::WriteWiper,
            PotCommand::ReadEeprom(_) => PotOp::ReadEeprom,
            PotCommand::WriteEeprom { .. } => PotOp::WriteEeprom,
            PotCommand::ReadOutputs => PotOp::ReadOutputs,
            PotCommand::WriteOutputs(_) => PotOp::WriteOutputs,
            PotCommand::ReadWriteProtect => PotOp::ReadWriteProtect,
            PotCommand::WriteProtect(_) => PotOp::WriteWriteProtect,
        }
    }

    /// The EEPROM word it addresses (0 for the others).
    pub fn address(self) -> u8 {
        match self {
            PotCommand::ReadEeprom(w) | PotCommand::WriteEeprom { word: w, .. } => w,
            _ => 0,
        }
    }

    /// Whether it changes the pot (a write).
    pub fn is_write(self) -> bool {
        matches!(
            self,
            PotCommand::WriteWiper(_)
                | PotCommand::WriteEeprom { .. }
                | PotCommand::WriteOutputs(_)
                | PotCommand::WriteProtect(_)
        )
    }

    /// The pot control word. Values are in range by construction except
    /// an EEPROM word above 13, which is truncated to 4 bits (use
    /// [`check_eeprom_word`] first; [`parse`](Self::parse) rejects it).
    pub fn to_word(self) -> u32 {
        let data = match self {
            PotCommand::WriteWiper(w) => w.value(),
            PotCommand::WriteEeprom { value, .. } => value,
            PotCommand::WriteOutputs(o) => o.bits(),
            PotCommand::WriteProtect(on) => u16::from(on),
            _ => 0,
        };
        let w = field::POT_OP.insert(0, u32::from(u8::from(self.op())));
        let w = field::POT_ADDRESS.insert(w, u32::from(self.address()));
        field::POT_DATA.insert(w, u32::from(data))
    }
}

quadlet_register! {
    /// The pot data register: the state and result of the last command.
    /// `ready` and `busy` are never both set; `error` says the command was
    /// refused (an EEPROM write while write-protected, or a word the pot
    /// control register could not decode).
    pub struct PotResult {
        /// The result below is valid, bit 31.
        ready, set_ready, with_ready: bool = field::RESULT_READY;
        /// A command is running on the SPI bus, bit 30.
        busy, set_busy, with_busy: bool = field::RESULT_BUSY;
        /// The last command was refused, bit 29.
        error, set_error, with_error: bool = field::RESULT_ERROR;
        /// Operation of the last command, bits 27:24.
        op_bits, set_op_bits, with_op_bits: u8 = field::RESULT_OP;
        /// EEPROM word of the last command, bits 23:20.
        address, set_address, with_address: u8 = field::RESULT_ADDRESS;
        /// The value read (or written), bits 15:0.
        data, set_data, with_data: u16 = field::RESULT_DATA;
    }
}

impl PotResult {
    /// The operation of the last command.
    pub fn op(self) -> PotOp {
        PotOp::from(self.op_bits())
    }
}

// --------------------------------------------------------------- encoder ---

quadlet_register! {
    /// Encoder data: the 24-bit count (bits 23:0) and the overflow flag
    /// (bit 24), set when the count went below 0 or above 0xFFFFFF since
    /// the last preload.
    pub struct EncoderData {
        /// The count, bits 23:0.
        count, set_count, with_count: u32 = field::ENC_COUNT;
        /// Overflow since the last preload, bit 24.
        overflow, set_overflow, with_overflow: bool = field::ENC_OVERFLOW;
    }
}

impl EncoderData {
    /// The count relative to [`ENCODER_MIDPOINT`].
    pub fn signed_counts(self) -> i32 {
        self.count() as i32 - ENCODER_MIDPOINT as i32
    }
}

/// An encoder preload: the value the counter takes (bits 23:0; 31:24 must
/// be 0). Writing it also clears the overflow flag.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct EncoderPreload(u32);

impl EncoderPreload {
    /// The midpoint preload the seed recommends.
    pub const MIDPOINT: EncoderPreload = EncoderPreload(ENCODER_MIDPOINT);

    /// A preload.
    ///
    /// # Errors
    /// [`Error::FieldRange`] above 0xFFFFFF.
    pub fn new(count: u32) -> Result<EncoderPreload> {
        check_max("encoder preload", u64::from(count), u64::from(ENCODER_MAX))?;
        Ok(EncoderPreload(count))
    }

    /// Decode a preload write.
    ///
    /// # Errors
    /// [`Error::InvalidValue`] when bits 31:24 are set.
    pub fn parse(word: u32) -> Result<EncoderPreload> {
        if field::ENC_PRELOAD_RESERVED.extract(word) != 0 {
            return Err(Error::InvalidValue {
                what: "Snake encoder preload (bits 31:24 must be 0)",
                value: word,
            });
        }
        Ok(EncoderPreload(field::ENC_PRELOAD.extract(word)))
    }

    /// The count.
    pub fn count(self) -> u32 {
        self.0
    }

    /// The register word.
    pub fn to_word(self) -> u32 {
        field::ENC_PRELOAD.insert(0, self.0)
    }
}

quadlet_register! {
    /// Encoder period: 768 kHz ticks between the last two encoder edges,
    /// signed by the direction of motion, bits 15:0 (saturating at
    /// +-32767 for a slow or stopped motor).
    pub struct EncoderPeriod {
        /// The raw 16 bits.
        bits, set_bits, with_bits: u16 = field::ENC_PERIOD;
    }
}

impl EncoderPeriod {
    /// From a signed tick count.
    pub fn from_ticks(ticks: i16) -> EncoderPeriod {
        EncoderPeriod::default().with_bits(ticks as u16)
    }

    /// The signed tick count.
    pub fn ticks(self) -> i16 {
        self.bits() as i16
    }

    /// Encoder counts per second this period means (0 when saturated or
    /// zero: too slow to measure).
    pub fn counts_per_second(self) -> f64 {
        let t = self.ticks();
        if t == 0 || t.unsigned_abs() >= i16::MAX as u16 {
            return 0.0;
        }
        f64::from(PERIOD_CLOCK_HZ) / f64::from(t)
    }
}

// ------------------------------------------------------------ block write ---

/// One channel's quadlet of the block write: bit 31 valid (write this
/// channel's DAC), bits 15:0 the motor command; bits 30:16 must be 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct ChannelCommand {
    /// The FPGA writes the DAC only when set.
    pub valid: bool,
    /// The motor command code.
    pub value: u16,
}

impl ChannelCommand {
    /// A command the FPGA applies.
    pub fn valid(value: u16) -> ChannelCommand {
        ChannelCommand { valid: true, value }
    }

    /// Decode a block-write quadlet.
    ///
    /// # Errors
    /// [`Error::InvalidValue`] when reserved bits are set, or the value is
    /// not 0 in an invalid quadlet.
    pub fn parse(word: u32) -> Result<ChannelCommand> {
        let valid = field::COMMAND_VALID.extract(word) == 1;
        let value = field::COMMAND_VALUE.extract(word) as u16;
        if field::COMMAND_RESERVED.extract(word) != 0 || (!valid && value != 0) {
            return Err(Error::InvalidValue {
                what: "Snake block-write quadlet",
                value: word,
            });
        }
        Ok(ChannelCommand { valid, value })
    }

    /// The quadlet (an invalid command carries no value).
    pub fn to_word(self) -> u32 {
        if self.valid {
            field::COMMAND_VALUE.insert(field::COMMAND_VALID.insert(0, 1), u32::from(self.value))
        } else {
            0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn status_follows_table_2() {
        let s = SnakeStatus(0xF7FF_FFFF);
        assert_eq!(s.unused(), 0xF);
        assert_eq!(s.board_id(), 7);
        assert!(s.watchdog_timeout());
        assert_eq!(s.faults(), 0x7F);
        assert_eq!(s.enable_mask(), 0xFF);
        assert_eq!(s.amp_enable(), 0xFF);
        let s = SnakeStatus::default()
            .with_board_id(0xA)
            .with_watchdog_timeout(true)
            .with_faults(0b100_0001)
            .with_enable_mask(0x12)
            .with_amp_enable(0x34);
        assert_eq!(s.raw(), 0x0AC1_1234);
        assert!(s.fault(1) && s.fault(7) && !s.fault(2) && !s.fault(0) && !s.fault(8));
        assert!(s.amp_enabled(3) && !s.amp_enabled(1));
    }

    #[test]
    fn power_control_masks() {
        let p = PowerControl::channel(3, true).unwrap();
        assert_eq!(p.raw(), 0x0404);
        assert_eq!(p.apply(0b0000_0001), 0b0000_0101);
        assert_eq!(PowerControl::channel(1, false).unwrap().apply(0x7F), 0x7E);
        assert_eq!(PowerControl::all(true).apply(0), 0x7F);
        // Bit 7 never sticks.
        assert_eq!(PowerControl(0xFFFF).apply(0), 0x7F);
        assert!(PowerControl::channel(0, true).is_err());
        assert!(PowerControl::channel(8, true).is_err());
    }

    #[test]
    fn adc_convention_adds_8192() {
        for (s, api) in [(-8192, 0), (-1, 8191), (0, 8192), (8191, 16383)] {
            let a = AdcData::from_signed(s, -s.max(-8191));
            assert_eq!(a.pot(), s);
            assert_eq!(a.pot_api(), api);
            assert_eq!(api_to_adc(api).unwrap(), s);
        }
        assert_eq!(AdcData::from_signed(-8192, 0).raw(), 0x2000_0000);
        assert_eq!(AdcData::from_signed(0, -1).raw(), 0x0000_3FFF);
        assert!(api_to_adc(16384).is_err());
        // Saturation, not wrap-around.
        assert_eq!(AdcData::from_signed(i16::MAX, i16::MIN).pot(), 8191);
        assert_eq!(AdcData::from_signed(i16::MAX, i16::MIN).current(), -8192);
        assert!((adc_api_to_volts(8192) - 1.25).abs() < 1e-12);
    }

    #[test]
    fn dac_words() {
        assert_eq!(DacCommand::MotorVoltage(0x1234).to_word(), 0x1234);
        assert_eq!(DacCommand::CurrentLimit(0xABCD).to_word(), 0x1_ABCD);
        for c in [DacCommand::MotorVoltage(7), DacCommand::CurrentLimit(65535)] {
            assert_eq!(DacCommand::parse(c.to_word()).unwrap(), c);
        }
        assert!(DacCommand::parse(0x2_0000).is_err());
        assert!((dac_to_volts(DAC_MIDPOINT) - 1.25).abs() < 1e-12);
    }

    #[test]
    fn feedback_gain_of_eq_1() {
        // Fig. 19 shows wiper 649 with FBGain 3.57727.
        let g = Wiper::new(649).unwrap().feedback_gain();
        assert!((g - 3.57727).abs() < 5e-6, "{g}");
        // Ends of the range: 12.1/11.5 and 22.1/1.5.
        assert!((Wiper::new(0).unwrap().feedback_gain() - 12.1 / 11.5).abs() < 1e-12);
        assert!((Wiper::new(1023).unwrap().feedback_gain() - 22.1 / 1.5).abs() < 1e-12);
        // "Nominally 2": 375.
        assert!((Wiper::NOMINAL.feedback_gain() - 2.0).abs() < 0.02);
        assert!(Wiper::new(1024).is_err());
    }

    #[test]
    fn pot_commands_round_trip_and_reject() {
        let all = [
            PotCommand::ReadWiper,
            PotCommand::WriteWiper(Wiper::new(1023).unwrap()),
            PotCommand::ReadEeprom(13),
            PotCommand::WriteEeprom {
                word: 5,
                value: 0xBEEF,
            },
            PotCommand::ReadOutputs,
            PotCommand::WriteOutputs(PotOutputs {
                speed_mode: true,
                o2: false,
            }),
            PotCommand::ReadWriteProtect,
            PotCommand::WriteProtect(true),
        ];
        for c in all {
            assert_eq!(PotCommand::parse(c.to_word()).unwrap(), c, "{c:?}");
        }
        assert_eq!(
            PotCommand::WriteEeprom {
                word: 5,
                value: 0xBEEF
            }
            .to_word(),
            0x4500_BEEF
        );
        for bad in [
            0x0000_0000u32, // NOP is not a command
            0x9000_0000,    // unknown op
            0x3E00_0000,    // EEPROM word 14
            0x2000_0400,    // wiper 1024
            0x6000_0004,    // outputs beyond 2 bits
            0x8000_0002,    // write protect 2
            0x1001_0000,    // reserved bits
            0x1000_0001,    // operand on a read
        ] {
            assert!(PotCommand::parse(bad).is_err(), "{bad:#x}");
        }
    }

    #[test]
    fn encoder_words() {
        let e = EncoderData(0x0180_0005);
        assert!(e.overflow());
        assert_eq!(e.count(), 0x80_0005);
        assert_eq!(e.signed_counts(), 5);
        assert_eq!(EncoderPreload::MIDPOINT.to_word(), 0x80_0000);
        assert!(EncoderPreload::new(0x100_0000).is_err());
        assert!(EncoderPreload::parse(0x0100_0000).is_err());
        assert_eq!(EncoderPeriod::from_ticks(-768).ticks(), -768);
        assert_eq!(EncoderPeriod::from_ticks(-768).raw(), 0xFD00);
        assert!((EncoderPeriod::from_ticks(-768).counts_per_second() + 1000.0).abs() < 1e-9);
        assert_eq!(EncoderPeriod::from_ticks(i16::MAX).counts_per_second(), 0.0);
    }

    #[test]
    fn block_write_quadlets() {
        assert_eq!(ChannelCommand::valid(0x8001).to_word(), 0x8000_8001);
        assert_eq!(ChannelCommand::default().to_word(), 0);
        assert_eq!(
            ChannelCommand::parse(0x8000_1234).unwrap(),
            ChannelCommand::valid(0x1234)
        );
        assert!(ChannelCommand::parse(0x4000_0000).is_err());
        assert!(ChannelCommand::parse(0x0000_0001).is_err());
    }
}
