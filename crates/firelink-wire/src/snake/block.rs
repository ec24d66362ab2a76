//! The node's real-time blocks (seed 001 Fig. 17), both at offset 0 and
//! of fixed size:
//!
//! - **block read**, 23 quadlets: STATUS (Table 2); the timestamp
//!   (49.152 MHz clocks since the previous block read); then, grouped by
//!   device, the ADC data of channels 1-7, their encoder counts and their
//!   encoder periods.
//! - **block write**, 7 quadlets: one per channel, bit 31 the valid bit
//!   (the FPGA writes that channel's motor DAC only when set), bits 15:0
//!   the motor command.
//!
//! Two tiers as for packets: checked views over bytes ([`ReadBlock`],
//! [`WriteBlock`]) and meaning types ([`ReadBlockRepr`],
//! [`WriteBlockRepr`]) with `parse`, `emit` and `buffer_len`.
//!
//! # Panics
//! After `new_checked` (or a successful `check_len`) no accessor panics:
//! per-channel getters return `None` and setters [`Error::OutOfRange`]
//! for a channel outside 1..=7.
//!
//! ```
//! use firelink_wire::snake::block::{WriteBlock, WriteBlockRepr, WRITE_BLOCK_QUADLETS};
//! let mut repr = WriteBlockRepr::default();
//! repr.set(2, Some(0x9000)).unwrap();                  // channel 2 only
//! let mut buf = [0xA5u8; 4 * WRITE_BLOCK_QUADLETS];
//! repr.emit(&mut buf).unwrap();
//! assert_eq!(&buf[4..8], &[0x80, 0x00, 0x90, 0x00]);   // valid bit + command
//! assert_eq!(&buf[0..4], &[0, 0, 0, 0]);               // channel 1 not written
//! let view = WriteBlock::new_checked(&buf[..]).unwrap();
//! assert_eq!(WriteBlockRepr::parse(&view).unwrap(), repr);
//! ```

use crate::error::{Error, Result};
use crate::field::{read_quadlet, write_quadlet};
use crate::qla::check_exact;
use crate::snake::registers::{AdcData, ChannelCommand, EncoderData, EncoderPeriod, SnakeStatus};
use crate::snake::{CHANNELS, check_channel};

/// Quadlet positions of the read block, each defined once.
mod field {
    /// STATUS.
    pub const STATUS: usize = 0;
    /// Timestamp.
    pub const TIMESTAMP: usize = 1;
    /// ADC data of channel 1; channel c at `ADC + c - 1`.
    pub const ADC: usize = 2;
    /// Encoder data of channel 1.
    pub const ENCODER: usize = ADC + super::CHANNELS;
    /// Encoder period of channel 1.
    pub const PERIOD: usize = ENCODER + super::CHANNELS;
    /// Quadlets in the read block.
    pub const READ_QUADLETS: usize = PERIOD + super::CHANNELS;
}

/// Quadlets of the block read.
pub const READ_BLOCK_QUADLETS: usize = field::READ_QUADLETS;
/// Bytes of the block read.
pub const READ_BLOCK_LEN: usize = 4 * READ_BLOCK_QUADLETS;
/// Quadlets of the block write: one per channel.
pub const WRITE_BLOCK_QUADLETS: usize = CHANNELS;
/// Bytes of the block write.
pub const WRITE_BLOCK_LEN: usize = 4 * WRITE_BLOCK_QUADLETS;

/// Quadlet index of `channel`'s entry in a section starting at `base`.
fn slot(base: usize, channel: u8) -> Option<usize> {
    check_channel(channel)
        .ok()
        .map(|c| base + usize::from(c) - 1)
}

/// A checked view of a block read's data.
#[derive(Debug, Clone)]
pub struct ReadBlock<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> ReadBlock<T> {
    /// A view that checks nothing (accessors read 0 where bytes are
    /// missing).
    pub fn new_unchecked(buffer: T) -> ReadBlock<T> {
        ReadBlock { buffer }
    }

    /// A view of exactly [`READ_BLOCK_QUADLETS`] quadlets.
    ///
    /// # Errors
    /// [`Error::NotQuadletAligned`] or [`Error::BlockSize`].
    pub fn new_checked(buffer: T) -> Result<ReadBlock<T>> {
        let view = ReadBlock { buffer };
        view.check_len()?;
        Ok(view)
    }

    /// Check the length.
    ///
    /// # Errors
    /// As [`new_checked`](Self::new_checked).
    pub fn check_len(&self) -> Result<()> {
        check_exact(
            "Snake block read",
            self.buffer.as_ref().len(),
            READ_BLOCK_QUADLETS,
        )
    }

    /// The bytes.
    pub fn as_bytes(&self) -> &[u8] {
        self.buffer.as_ref()
    }

    /// STATUS.
    pub fn status(&self) -> SnakeStatus {
        SnakeStatus(read_quadlet(self.as_bytes(), field::STATUS))
    }

    /// 49.152 MHz clocks since the previous block read.
    pub fn timestamp(&self) -> u32 {
        read_quadlet(self.as_bytes(), field::TIMESTAMP)
    }

    /// Channel `channel`'s ADC data.
    pub fn adc(&self, channel: u8) -> Option<AdcData> {
        slot(field::ADC, channel).map(|q| AdcData(read_quadlet(self.as_bytes(), q)))
    }

    /// Channel `channel`'s encoder count.
    pub fn encoder(&self, channel: u8) -> Option<EncoderData> {
        slot(field::ENCODER, channel).map(|q| EncoderData(read_quadlet(self.as_bytes(), q)))
    }

    /// Channel `channel`'s encoder period.
    pub fn period(&self, channel: u8) -> Option<EncoderPeriod> {
        slot(field::PERIOD, channel).map(|q| EncoderPeriod(read_quadlet(self.as_bytes(), q)))
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> ReadBlock<T> {
    fn put(&mut self, q: usize, value: u32) {
        write_quadlet(self.buffer.as_mut(), q, value);
    }

    /// Set STATUS.
    pub fn set_status(&mut self, status: SnakeStatus) {
        self.put(field::STATUS, status.raw());
    }

    /// Set the timestamp.
    pub fn set_timestamp(&mut self, clocks: u32) {
        self.put(field::TIMESTAMP, clocks);
    }

    /// Set channel `channel`'s ADC data.
    ///
    /// # Errors
    /// [`Error::OutOfRange`] for a channel outside 1..=7.
    pub fn set_adc(&mut self, channel: u8, adc: AdcData) -> Result<()> {
        let q = field::ADC + usize::from(check_channel(channel)?) - 1;
        self.put(q, adc.raw());
        Ok(())
    }

    /// Set channel `channel`'s encoder count.
    ///
    /// # Errors
    /// [`Error::OutOfRange`] for a channel outside 1..=7.
    pub fn set_encoder(&mut self, channel: u8, encoder: EncoderData) -> Result<()> {
        let q = field::ENCODER + usize::from(check_channel(channel)?) - 1;
        self.put(q, encoder.raw());
        Ok(())
    }

    /// Set channel `channel`'s encoder period.
    ///
    /// # Errors
    /// [`Error::OutOfRange`] for a channel outside 1..=7.
    pub fn set_period(&mut self, channel: u8, period: EncoderPeriod) -> Result<()> {
        let q = field::PERIOD + usize::from(check_channel(channel)?) - 1;
        self.put(q, period.raw());
        Ok(())
    }
}

/// One channel's feedback in a block read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct ChannelFeedback {
    /// Potentiometer and motor current.
    pub adc: AdcData,
    /// Encoder count and overflow.
    pub encoder: EncoderData,
    /// Encoder period.
    pub period: EncoderPeriod,
}

/// The meaning of a block read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct ReadBlockRepr {
    /// STATUS.
    pub status: SnakeStatus,
    /// 49.152 MHz clocks since the previous block read.
    pub timestamp: u32,
    /// Channels 1-7 at indices 0-6.
    pub channels: [ChannelFeedback; CHANNELS],
}

impl ReadBlockRepr {
    /// Channel `channel`'s feedback (1..=7).
    pub fn channel(&self, channel: u8) -> Option<&ChannelFeedback> {
        check_channel(channel)
            .ok()
            .and_then(|c| self.channels.get(usize::from(c) - 1))
    }

    /// Parse a checked view (every bit pattern has a meaning).
    ///
    /// # Errors
    /// The length errors of [`ReadBlock::check_len`].
    pub fn parse<T: AsRef<[u8]>>(block: &ReadBlock<T>) -> Result<ReadBlockRepr> {
        block.check_len()?;
        let mut repr = ReadBlockRepr {
            status: block.status(),
            timestamp: block.timestamp(),
            channels: [ChannelFeedback::default(); CHANNELS],
        };
        for (c, ch) in (1u8..).zip(repr.channels.iter_mut()) {
            *ch = ChannelFeedback {
                adc: block.adc(c).unwrap_or_default(),
                encoder: block.encoder(c).unwrap_or_default(),
                period: block.period(c).unwrap_or_default(),
            };
        }
        Ok(repr)
    }

    /// Bytes [`emit`](Self::emit) writes.
    pub fn buffer_len(&self) -> usize {
        READ_BLOCK_LEN
    }

    /// Write the block into the front of `buf`; returns its length.
    ///
    /// # Errors
    /// [`Error::BufferTooSmall`].
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize> {
        let available = buf.len();
        let out = buf.get_mut(..READ_BLOCK_LEN).ok_or(Error::BufferTooSmall {
            what: "Snake block read",
            needed: READ_BLOCK_LEN,
            available,
        })?;
        let mut view = ReadBlock::new_unchecked(out);
        view.set_status(self.status);
        view.set_timestamp(self.timestamp);
        for (c, ch) in (1u8..).zip(self.channels.iter()) {
            view.set_adc(c, ch.adc)?;
            view.set_encoder(c, ch.encoder)?;
            view.set_period(c, ch.period)?;
        }
        Ok(READ_BLOCK_LEN)
    }
}

/// A checked view of a block write's data.
#[derive(Debug, Clone)]
pub struct WriteBlock<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> WriteBlock<T> {
    /// A view that checks nothing.
    pub fn new_unchecked(buffer: T) -> WriteBlock<T> {
        WriteBlock { buffer }
    }

    /// A view of exactly [`WRITE_BLOCK_QUADLETS`] quadlets.
    ///
    /// # Errors
    /// [`Error::NotQuadletAligned`] or [`Error::BlockSize`].
    pub fn new_checked(buffer: T) -> Result<WriteBlock<T>> {
        let view = WriteBlock { buffer };
        view.check_len()?;
        Ok(view)
    }

    /// Check the length.
    ///
    /// # Errors
    /// As [`new_checked`](Self::new_checked).
    pub fn check_len(&self) -> Result<()> {
        check_exact(
            "Snake block write",
            self.buffer.as_ref().len(),
            WRITE_BLOCK_QUADLETS,
        )
    }

    /// The raw quadlet of `channel`.
    pub fn word(&self, channel: u8) -> Option<u32> {
        slot(0, channel).map(|q| read_quadlet(self.buffer.as_ref(), q))
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> WriteBlock<T> {
    /// Set `channel`'s quadlet.
    ///
    /// # Errors
    /// [`Error::OutOfRange`] for a channel outside 1..=7.
    pub fn set_command(&mut self, channel: u8, command: ChannelCommand) -> Result<()> {
        let q = usize::from(check_channel(channel)?) - 1;
        write_quadlet(self.buffer.as_mut(), q, command.to_word());
        Ok(())
    }
}

/// The meaning of a block write: per channel, the motor command to apply
/// (`Some`, valid bit set) or nothing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct WriteBlockRepr {
    /// Channels 1-7 at indices 0-6.
    pub commands: [Option<u16>; CHANNELS],
}

impl WriteBlockRepr {
    /// Set `channel`'s command (`None`: valid bit clear).
    ///
    /// # Errors
    /// [`Error::OutOfRange`] for a channel outside 1..=7.
    pub fn set(&mut self, channel: u8, command: Option<u16>) -> Result<()> {
        let i = usize::from(check_channel(channel)?) - 1;
        if let Some(c) = self.commands.get_mut(i) {
            *c = command;
        }
        Ok(())
    }

    /// `channel`'s command.
    pub fn get(&self, channel: u8) -> Option<u16> {
        let i = usize::from(check_channel(channel).ok()?) - 1;
        self.commands.get(i).copied().flatten()
    }

    /// Parse a view; every quadlet must be well formed (a block with one
    /// bad quadlet is refused whole, never half-applied).
    ///
    /// # Errors
    /// The length errors of [`WriteBlock::check_len`]; the first
    /// [`ChannelCommand::parse`] error.
    pub fn parse<T: AsRef<[u8]>>(block: &WriteBlock<T>) -> Result<WriteBlockRepr> {
        block.check_len()?;
        let mut repr = WriteBlockRepr::default();
        for (c, slot) in (1u8..).zip(repr.commands.iter_mut()) {
            let command = ChannelCommand::parse(block.word(c).unwrap_or(0))?;
            *slot = command.valid.then_some(command.value);
        }
        Ok(repr)
    }

    /// Bytes [`emit`](Self::emit) writes.
    pub fn buffer_len(&self) -> usize {
        WRITE_BLOCK_LEN
    }

    /// Write the block into the front of `buf`; returns its length.
    ///
    /// # Errors
    /// [`Error::BufferTooSmall`].
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize> {
        let available = buf.len();
        let out = buf
            .get_mut(..WRITE_BLOCK_LEN)
            .ok_or(Error::BufferTooSmall {
                what: "Snake block write",
                needed: WRITE_BLOCK_LEN,
                available,
            })?;
        let mut view = WriteBlock::new_unchecked(out);
        for (c, command) in (1u8..).zip(self.commands.iter()) {
            let word = command.map_or(ChannelCommand::default(), ChannelCommand::valid);
            view.set_command(c, word)?;
        }
        Ok(WRITE_BLOCK_LEN)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::snake::registers::ENCODER_MIDPOINT;

    #[test]
    fn read_block_layout() {
        assert_eq!(READ_BLOCK_QUADLETS, 23);
        let mut repr = ReadBlockRepr {
            status: SnakeStatus(0x0300_7F7F),
            timestamp: 49_152,
            ..ReadBlockRepr::default()
        };
        for (i, ch) in repr.channels.iter_mut().enumerate() {
            let i16v = i as i16;
            ch.adc = AdcData::from_signed(100 * i16v, -100 * i16v);
            ch.encoder = EncoderData::default().with_count(ENCODER_MIDPOINT + i as u32);
            ch.period = EncoderPeriod::from_ticks(-(i16v + 1));
        }
        let mut buf = [0xA5u8; READ_BLOCK_LEN];
        assert_eq!(repr.emit(&mut buf).unwrap(), READ_BLOCK_LEN);
        let q = |i: usize| read_quadlet(&buf, i);
        assert_eq!(q(0), 0x0300_7F7F);
        assert_eq!(q(1), 49_152);
        // Channel 7's ADC, encoder and period quadlets.
        assert_eq!(q(8), AdcData::from_signed(600, -600).raw());
        assert_eq!(q(15), ENCODER_MIDPOINT + 6);
        assert_eq!(q(22), 0xFFF9);
        let view = ReadBlock::new_checked(&buf[..]).unwrap();
        assert_eq!(ReadBlockRepr::parse(&view).unwrap(), repr);
        assert_eq!(view.adc(8), None);
        assert_eq!(view.adc(0), None);
        assert!(ReadBlock::new_checked(&buf[..88]).is_err());
        assert!(ReadBlock::new_checked(&buf[..91]).is_err());
        assert!(repr.emit(&mut [0u8; 91]).is_err());
    }

    #[test]
    fn write_block_valid_bits() {
        let mut repr = WriteBlockRepr::default();
        repr.set(1, Some(0)).unwrap();
        repr.set(7, Some(0xFFFF)).unwrap();
        assert!(repr.set(8, Some(1)).is_err());
        let mut buf = [0xA5u8; WRITE_BLOCK_LEN];
        repr.emit(&mut buf).unwrap();
        assert_eq!(read_quadlet(&buf, 0), 0x8000_0000);
        assert_eq!(read_quadlet(&buf, 6), 0x8000_FFFF);
        for q in 1..6 {
            assert_eq!(read_quadlet(&buf, q), 0);
        }
        let view = WriteBlock::new_checked(&buf[..]).unwrap();
        let back = WriteBlockRepr::parse(&view).unwrap();
        assert_eq!(back, repr);
        assert_eq!(back.get(1), Some(0));
        assert_eq!(back.get(2), None);
        // One malformed quadlet refuses the whole block.
        write_quadlet(&mut buf, 3, 0x0001_0000);
        assert!(WriteBlockRepr::parse(&WriteBlock::new_checked(&buf[..]).unwrap()).is_err());
        assert!(WriteBlock::new_checked(&buf[..24]).is_err());
    }
}
