//! Fig. 18's second layer for one node: the local buffers of a Snake
//! node, filled by the block read of `LatchAllInputs` and emptied by the
//! block write of `ApplyAllOutputs`, with a valid bit per channel.
//!
//! Getters read the last latched block in the seed's API conventions (the
//! ADC plus 8192, the raw 24-bit encoder count, the raw period); setters
//! mark their channel valid so the FPGA writes it, and only it, with the
//! next block write. Channels are numbered 1 to 7 (Table 1).

use firelink_wire::phy::SYSTEM_CLOCK_HZ;
use firelink_wire::snake::block::{ReadBlockRepr, WriteBlockRepr};
use firelink_wire::snake::registers::{ALL_CHANNELS, PowerControl, SnakeStatus, check_eeprom_word};
use firelink_wire::snake::{CHANNELS, check_channel};

use crate::error::{HostError, Result};

/// What discovery learned about one node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SnakeNodeInfo {
    /// Board ID from the rotary switch.
    pub board_id: u8,
    /// Physical node ID on the bus (bus generation dependent).
    pub node: u8,
    /// The version register.
    pub version: u32,
}

/// A channel out of range, as a host error.
pub(crate) fn bad_channel(channel: u8) -> HostError {
    HostError::InvalidRequest {
        what: "Snake channel (1..=7)",
        value: u32::from(channel),
    }
}

/// Check a channel number (1..=7).
///
/// # Errors
/// [`HostError::InvalidRequest`] naming the channel.
pub fn channel(channel: u8) -> Result<u8> {
    check_channel(channel).map_err(|_| bad_channel(channel))
}

/// An EEPROM location in the seed's addressing: bits 7-4 of the index the
/// channel (1..=7), bits 3-0 the word (0..=13) (§7.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct EepromIndex {
    /// The channel, 1..=7.
    pub channel: u8,
    /// The word, 0..=13.
    pub word: u8,
}

impl EepromIndex {
    /// Decode an API index.
    ///
    /// # Errors
    /// [`HostError::InvalidRequest`] when the index has bits above 7, or
    /// names a channel outside 1..=7 or a word above 13.
    pub fn from_index(index: u32) -> Result<EepromIndex> {
        if index > 0xFF {
            return Err(HostError::InvalidRequest {
                what: "EEPROM index (bits 7-4 channel, 3-0 word)",
                value: index,
            });
        }
        EepromIndex::new((index >> 4) as u8, (index & 0xF) as u8)
    }

    /// A location.
    ///
    /// # Errors
    /// [`HostError::InvalidRequest`] for a channel outside 1..=7 or a word
    /// above 13.
    pub fn new(channel: u8, word: u8) -> Result<EepromIndex> {
        self::channel(channel)?;
        check_eeprom_word(word).map_err(|_| HostError::InvalidRequest {
            what: "EEPROM word (0..=13)",
            value: u32::from(word),
        })?;
        Ok(EepromIndex { channel, word })
    }

    /// The API index.
    pub fn index(self) -> u32 {
        (u32::from(self.channel) << 4) | u32::from(self.word)
    }

    /// The location after this one in the same channel (the second word of
    /// a float).
    ///
    /// # Errors
    /// [`HostError::InvalidRequest`] past word 13: a float needs two words,
    /// so its first word is at most 12.
    pub fn next(self) -> Result<EepromIndex> {
        EepromIndex::new(self.channel, self.word + 1).map_err(|_| HostError::InvalidRequest {
            what: "EEPROM float index: the first of its two words must be 0..=12",
            value: self.index(),
        })
    }
}

/// A float split into two EEPROM words at the library level (§7.2): the
/// high 16 bits first.
pub fn float_to_words(value: f32) -> [u16; 2] {
    let bits = value.to_bits();
    [(bits >> 16) as u16, bits as u16]
}

/// The float stored in two EEPROM words (high first).
pub fn words_to_float(words: [u16; 2]) -> f32 {
    f32::from_bits((u32::from(words[0]) << 16) | u32::from(words[1]))
}

/// One node's local buffers.
#[derive(Debug, Clone)]
pub struct SnakeNodeIo {
    info: SnakeNodeInfo,
    input: ReadBlockRepr,
    input_valid: bool,
    output: WriteBlockRepr,
    /// Amplifier changes for the next apply: (mask, enables).
    power: Option<PowerControl>,
}

impl SnakeNodeIo {
    /// Buffers for a node; inputs start invalid, no output valid.
    pub fn new(info: SnakeNodeInfo) -> SnakeNodeIo {
        SnakeNodeIo {
            info,
            input: ReadBlockRepr::default(),
            input_valid: false,
            output: WriteBlockRepr::default(),
            power: None,
        }
    }

    /// Identity.
    pub fn info(&self) -> &SnakeNodeInfo {
        &self.info
    }

    /// Board ID.
    pub fn board_id(&self) -> u8 {
        self.info.board_id
    }

    pub(crate) fn set_info(&mut self, info: SnakeNodeInfo) {
        self.info = info;
    }

    pub(crate) fn latch(&mut self, input: ReadBlockRepr) {
        self.input = input;
        self.input_valid = true;
    }

    pub(crate) fn invalidate(&mut self) {
        self.input_valid = false;
    }

    /// Whether the inputs were latched in the last cycle.
    pub fn is_valid(&self) -> bool {
        self.input_valid
    }

    /// The whole last block read.
    pub fn input(&self) -> &ReadBlockRepr {
        &self.input
    }

    /// `GetStatus`: STATUS from the last latch (Table 2).
    pub fn status(&self) -> SnakeStatus {
        self.input.status
    }

    /// `GetTimestamp`: 49.152 MHz clocks between the last two latches.
    pub fn timestamp(&self) -> u32 {
        self.input.timestamp
    }

    /// The timestamp in seconds.
    pub fn timestamp_seconds(&self) -> f64 {
        f64::from(self.input.timestamp) / f64::from(SYSTEM_CLOCK_HZ)
    }

    fn feedback(&self, ch: u8) -> Result<&firelink_wire::snake::block::ChannelFeedback> {
        self.input
            .channel(channel(ch)?)
            .ok_or_else(|| bad_channel(ch))
    }

    /// `GetMotorCurrent`: the current monitor, ADC + 8192 (0..=16383).
    ///
    /// # Errors
    /// [`HostError::InvalidRequest`] for a channel outside 1..=7 (so for
    /// every getter below).
    pub fn motor_current(&self, ch: u8) -> Result<u16> {
        Ok(self.feedback(ch)?.adc.current_api())
    }

    /// `GetAnalogPosition`: the potentiometer, ADC + 8192 (0..=16383).
    ///
    /// # Errors
    /// As [`motor_current`](Self::motor_current).
    pub fn analog_position(&self, ch: u8) -> Result<u16> {
        Ok(self.feedback(ch)?.adc.pot_api())
    }

    /// `GetEncoderPosition`: the raw 24-bit count.
    ///
    /// # Errors
    /// As [`motor_current`](Self::motor_current).
    pub fn encoder_position(&self, ch: u8) -> Result<u32> {
        Ok(self.feedback(ch)?.encoder.count())
    }

    /// The encoder's overflow flag (the count left 0..=0xFFFFFF since the
    /// last preload).
    ///
    /// # Errors
    /// As [`motor_current`](Self::motor_current).
    pub fn encoder_overflow(&self, ch: u8) -> Result<bool> {
        Ok(self.feedback(ch)?.encoder.overflow())
    }

    /// The encoder count relative to the midpoint preload.
    ///
    /// # Errors
    /// As [`motor_current`](Self::motor_current).
    pub fn encoder_counts(&self, ch: u8) -> Result<i32> {
        Ok(self.feedback(ch)?.encoder.signed_counts())
    }

    /// `GetEncoderVelocity`: the raw period, signed 768 kHz ticks.
    ///
    /// # Errors
    /// As [`motor_current`](Self::motor_current).
    pub fn encoder_period(&self, ch: u8) -> Result<i16> {
        Ok(self.feedback(ch)?.period.ticks())
    }

    /// The encoder velocity in counts per second from the period (0 when
    /// too slow to measure).
    ///
    /// # Errors
    /// As [`motor_current`](Self::motor_current).
    pub fn encoder_velocity(&self, ch: u8) -> Result<f64> {
        Ok(self.feedback(ch)?.period.counts_per_second())
    }

    /// Whether channel `ch`'s amplifier was enabled at the last latch.
    ///
    /// # Errors
    /// As [`motor_current`](Self::motor_current).
    pub fn amplifier_enabled(&self, ch: u8) -> Result<bool> {
        Ok(self.input.status.amp_enabled(channel(ch)?))
    }

    /// Whether channel `ch`'s fault line was asserted at the last latch.
    ///
    /// # Errors
    /// As [`motor_current`](Self::motor_current).
    pub fn amplifier_fault(&self, ch: u8) -> Result<bool> {
        Ok(self.input.status.fault(channel(ch)?))
    }

    /// `SetMotorVoltage`: the motor DAC code for the next apply; marks the
    /// channel valid.
    ///
    /// # Errors
    /// [`HostError::InvalidRequest`] for a channel outside 1..=7.
    pub fn set_motor_voltage(&mut self, ch: u8, code: u16) -> Result<()> {
        self.output
            .set(channel(ch)?, Some(code))
            .map_err(|_| bad_channel(ch))
    }

    /// The motor command that the next apply writes to channel `ch`
    /// (`None`: its valid bit is clear).
    pub fn pending_motor_voltage(&self, ch: u8) -> Option<u16> {
        self.output.get(ch)
    }

    /// Clear channel `ch`'s valid bit: the next apply leaves it alone.
    ///
    /// # Errors
    /// [`HostError::InvalidRequest`] for a channel outside 1..=7.
    pub fn clear_valid(&mut self, ch: u8) -> Result<()> {
        self.output
            .set(channel(ch)?, None)
            .map_err(|_| bad_channel(ch))
    }

    /// Ask for channel `ch`'s amplifier on or off with the next apply
    /// (collected into one power-control write with its enable mask).
    ///
    /// # Errors
    /// [`HostError::InvalidRequest`] for a channel outside 1..=7.
    pub fn set_amplifier_enable(&mut self, ch: u8, on: bool) -> Result<()> {
        let bit = 1u8 << (channel(ch)? - 1);
        let p = self.power.unwrap_or_default();
        let enable = if on {
            p.enable() | bit
        } else {
            p.enable() & !bit
        };
        self.power = Some(p.with_mask(p.mask() | bit).with_enable(enable));
        Ok(())
    }

    /// Ask for every amplifier on or off with the next apply.
    pub fn set_all_amplifiers(&mut self, on: bool) {
        self.power = Some(PowerControl::all(on));
    }

    /// The power-control word the next apply writes, if any.
    pub fn pending_power(&self) -> Option<PowerControl> {
        self.power
    }

    /// The block write for the next apply.
    pub fn output(&self) -> &WriteBlockRepr {
        &self.output
    }

    /// After an apply: valid bits and power requests are cleared.
    pub(crate) fn outputs_applied(&mut self) {
        self.output = WriteBlockRepr::default();
        self.power = None;
    }

    /// Every channel's motor at the midpoint (marked valid) and every
    /// amplifier off with the next apply.
    pub fn safe_outputs(&mut self) {
        for ch in 1..=CHANNELS as u8 {
            let _ = self.set_motor_voltage(ch, firelink_wire::snake::registers::DAC_MIDPOINT);
        }
        self.power = Some(PowerControl::all(false));
    }

    /// Whether every channel in `mask` (bit c-1 = channel c) had its
    /// amplifier on at the last latch.
    pub fn amplifiers_on(&self, mask: u8) -> bool {
        let m = mask & ALL_CHANNELS;
        self.input.status.amp_enable() & m == m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eeprom_indices() {
        let i = EepromIndex::from_index(0x3D).unwrap();
        assert_eq!((i.channel, i.word), (3, 13));
        assert_eq!(i.index(), 0x3D);
        for bad in [0x0Du32, 0x8D, 0x3E, 0x100, 0xFFFF_FFFF] {
            assert!(EepromIndex::from_index(bad).is_err(), "{bad:#x}");
        }
        assert!(EepromIndex::new(3, 12).unwrap().next().is_ok());
        assert!(EepromIndex::new(3, 13).unwrap().next().is_err());
    }

    #[test]
    fn floats_in_two_words() {
        for x in [
            0.0f32,
            -1.5,
            3.57727,
            f32::MAX,
            f32::MIN_POSITIVE,
            f32::INFINITY,
        ] {
            assert_eq!(words_to_float(float_to_words(x)).to_bits(), x.to_bits());
        }
        assert_eq!(float_to_words(1.0), [0x3F80, 0x0000]);
    }

    #[test]
    fn valid_bits_and_power() {
        let mut n = SnakeNodeIo::new(SnakeNodeInfo {
            board_id: 1,
            node: 0,
            version: 0,
        });
        n.set_motor_voltage(3, 0x9000).unwrap();
        assert_eq!(n.output().commands[2], Some(0x9000));
        assert_eq!(n.output().commands[0], None);
        assert!(n.set_motor_voltage(8, 0).is_err());
        assert!(n.set_motor_voltage(0, 0).is_err());
        n.set_amplifier_enable(2, true).unwrap();
        n.set_amplifier_enable(5, false).unwrap();
        let p = n.pending_power().unwrap();
        assert_eq!((p.mask(), p.enable()), (0b1_0010, 0b10));
        n.outputs_applied();
        assert_eq!(n.output().commands, [None; 7]);
        assert!(n.pending_power().is_none());
        assert!(n.motor_current(9).is_err());
    }
}
