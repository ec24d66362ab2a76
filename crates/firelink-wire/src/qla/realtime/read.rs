//! The real-time read block (`fpga-board.md` §4): STATUS, the timestamp, the
//! digital inputs, temperatures and the per-axis ADC, encoder and motor words,
//! as a checked view over bytes and a meaning type with fixed per-axis arrays.

use super::*;

layout_view! {
    /// A checked view of a real-time read block (`fpga-board.md` §4).
    pub struct ReadBlock;
    what: "real-time read block",
    quadlets: read_block_quadlets,
}

impl<T: AsRef<[u8]>> ReadBlock<T> {
    fn entry(&self, section: Section, index: usize) -> Option<u32> {
        let q = self.layout.quadlet(section, index).ok()?;
        Some(read_quadlet(self.buffer.as_ref(), q))
    }

    /// Quadlet 0: 49.152 MHz clocks since the previous real-time read or query.
    pub fn timestamp(&self) -> u32 {
        field::TIMESTAMP.get(self.buffer.as_ref())
    }

    /// Quadlet 1: STATUS.
    pub fn status(&self) -> StatusRead {
        StatusRead(field::STATUS.get(self.buffer.as_ref()))
    }

    /// Quadlet 2: DIGITAL_IN.
    pub fn digital_in(&self) -> DigitalIn {
        DigitalIn(field::DIGITAL_IN.get(self.buffer.as_ref()))
    }

    /// Quadlet 3: TEMPERATURE.
    pub fn temperature(&self) -> Temperature {
        Temperature(field::TEMPERATURE.get(self.buffer.as_ref()))
    }

    /// ADC of 0-based `motor`.
    pub fn adc(&self, motor: usize) -> Option<AdcWord> {
        self.entry(Section::Adc, motor).map(AdcWord)
    }

    /// ENC_POSITION of 0-based `encoder`.
    pub fn enc_position(&self, encoder: usize) -> Option<EncPosition> {
        self.entry(Section::EncPosition, encoder).map(EncPosition)
    }

    /// ENC_PERIOD of 0-based `encoder`.
    pub fn enc_period(&self, encoder: usize) -> Option<EncPeriod> {
        self.entry(Section::EncPeriod, encoder).map(EncPeriod)
    }

    /// ENC_QTR1 of 0-based `encoder`.
    pub fn enc_qtr1(&self, encoder: usize) -> Option<EncQuarter> {
        self.entry(Section::EncQtr1, encoder).map(EncQuarter)
    }

    /// ENC_QTR5 of 0-based `encoder`.
    pub fn enc_qtr5(&self, encoder: usize) -> Option<EncQuarter> {
        self.entry(Section::EncQtr5, encoder).map(EncQuarter)
    }

    /// ENC_RUN of 0-based `encoder`.
    pub fn enc_run(&self, encoder: usize) -> Option<EncRun> {
        self.entry(Section::EncRun, encoder).map(EncRun)
    }

    /// MOTOR_STATUS of 0-based `motor` (Rev 8; always `None` before Rev 8).
    pub fn motor_status(&self, motor: usize) -> Option<MotorStatus> {
        self.entry(Section::MotorStatus, motor).map(MotorStatus)
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> ReadBlock<T> {
    fn set_entry(&mut self, section: Section, index: usize, value: u32) -> Result<()> {
        let q = self.layout.quadlet(section, index)?;
        write_quadlet(self.buffer.as_mut(), q, value);
        Ok(())
    }

    /// Set the timestamp.
    pub fn set_timestamp(&mut self, clocks: u32) {
        field::TIMESTAMP.set(self.buffer.as_mut(), clocks);
    }

    /// Set STATUS.
    pub fn set_status(&mut self, status: StatusRead) {
        field::STATUS.set(self.buffer.as_mut(), status.0);
    }

    /// Set DIGITAL_IN.
    pub fn set_digital_in(&mut self, digital_in: DigitalIn) {
        field::DIGITAL_IN.set(self.buffer.as_mut(), digital_in.0);
    }

    /// Set TEMPERATURE.
    pub fn set_temperature(&mut self, temperature: Temperature) {
        field::TEMPERATURE.set(self.buffer.as_mut(), temperature.0);
    }

    /// Set the ADC of 0-based `motor`.
    ///
    /// # Errors
    /// [`Error::Index`] for a motor the layout does not have.
    pub fn set_adc(&mut self, motor: usize, adc: AdcWord) -> Result<()> {
        self.set_entry(Section::Adc, motor, adc.0)
    }

    /// Set ENC_POSITION of 0-based `encoder`.
    ///
    /// # Errors
    /// [`Error::Index`] for an encoder the layout does not have.
    pub fn set_enc_position(&mut self, encoder: usize, value: EncPosition) -> Result<()> {
        self.set_entry(Section::EncPosition, encoder, value.0)
    }

    /// Set ENC_PERIOD of 0-based `encoder`.
    ///
    /// # Errors
    /// [`Error::Index`] for an encoder the layout does not have.
    pub fn set_enc_period(&mut self, encoder: usize, value: EncPeriod) -> Result<()> {
        self.set_entry(Section::EncPeriod, encoder, value.0)
    }

    /// Set ENC_QTR1 of 0-based `encoder`.
    ///
    /// # Errors
    /// [`Error::Index`] for an encoder the layout does not have.
    pub fn set_enc_qtr1(&mut self, encoder: usize, value: EncQuarter) -> Result<()> {
        self.set_entry(Section::EncQtr1, encoder, value.0)
    }

    /// Set ENC_QTR5 of 0-based `encoder`.
    ///
    /// # Errors
    /// [`Error::Index`] for an encoder the layout does not have.
    pub fn set_enc_qtr5(&mut self, encoder: usize, value: EncQuarter) -> Result<()> {
        self.set_entry(Section::EncQtr5, encoder, value.0)
    }

    /// Set ENC_RUN of 0-based `encoder`.
    ///
    /// # Errors
    /// [`Error::Index`] for an encoder the layout does not have.
    pub fn set_enc_run(&mut self, encoder: usize, value: EncRun) -> Result<()> {
        self.set_entry(Section::EncRun, encoder, value.0)
    }

    /// Set MOTOR_STATUS of 0-based `motor` (Rev 8).
    ///
    /// # Errors
    /// [`Error::Index`] for a motor the layout does not have, and always on
    /// Rev 7 (no MOTOR_STATUS block).
    pub fn set_motor_status(&mut self, motor: usize, value: MotorStatus) -> Result<()> {
        self.set_entry(Section::MotorStatus, motor, value.0)
    }

    /// Set every quadlet of axis `axis` (0-based: its motor's and its
    /// encoder's) at once, the layout's section table worked out once;
    /// the encoder sections it does not have (Rev 4) and MOTOR_STATUS
    /// before Rev 8 are left alone.
    ///
    /// # Errors
    /// [`Error::Index`] for an axis beyond the layout's motors or encoders.
    pub fn set_axis(
        &mut self,
        axis: usize,
        motor: MotorReading,
        encoder: EncoderReading,
    ) -> Result<()> {
        let (m, e) = (self.layout.motors(), self.layout.encoders());
        if axis >= m || axis >= e {
            return Err(Error::Index {
                what: "axis",
                index: axis,
                count: m.min(e),
            });
        }
        let sections = self.layout.encoder_sections();
        let encoder_start = field::READ_FIXED_QUADLETS + m;
        let buf = self.buffer.as_mut();
        write_quadlet(buf, field::READ_FIXED_QUADLETS + axis, motor.adc.0);
        let words = [
            encoder.position.0,
            encoder.period.0,
            encoder.qtr1.0,
            encoder.qtr5.0,
            encoder.run.0,
        ];
        for (k, word) in words.into_iter().enumerate().take(sections) {
            write_quadlet(buf, encoder_start + k * e + axis, word);
        }
        if self.layout.format() == BlockFormat::Rev8 {
            write_quadlet(buf, encoder_start + sections * e + axis, motor.status.0);
        }
        Ok(())
    }
}

/// One motor's quadlets of the read block.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct MotorReading {
    /// ADC: potentiometer and motor current.
    pub adc: AdcWord,
    /// MOTOR_STATUS (Rev 8; zero before Rev 8).
    pub status: MotorStatus,
}

/// One encoder's quadlets of the read block.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct EncoderReading {
    /// ENC_POSITION.
    pub position: EncPosition,
    /// ENC_PERIOD.
    pub period: EncPeriod,
    /// ENC_QTR1.
    pub qtr1: EncQuarter,
    /// ENC_QTR5.
    pub qtr5: EncQuarter,
    /// ENC_RUN.
    pub run: EncRun,
}

/// The meaning of a real-time read block (`fpga-board.md` §4).
///
/// Entries beyond the layout's motors and encoders are not on the wire:
/// [`parse`](Self::parse) leaves them zero and [`emit`](Self::emit) ignores
/// them, as it ignores `status` of motors before Rev 8.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ReadBlockRepr {
    /// The layout.
    pub layout: BoardLayout,
    /// 49.152 MHz clocks since the previous real-time read or query.
    pub timestamp: u32,
    /// STATUS.
    pub status: StatusRead,
    /// DIGITAL_IN.
    pub digital_in: DigitalIn,
    /// TEMPERATURE.
    pub temperature: Temperature,
    /// Per-motor quadlets, index 0 = motor 1.
    pub motor: [MotorReading; MAX_AXES],
    /// Per-encoder quadlets, index 0 = encoder 1.
    pub encoder: [EncoderReading; MAX_AXES],
}

/// A big-endian quadlet (0 for a short chunk).
#[inline]
fn be_quadlet(q: &[u8]) -> u32 {
    match *q {
        [a, b, c, d] => u32::from_be_bytes([a, b, c, d]),
        _ => 0,
    }
}

impl ReadBlockRepr {
    /// A block of all zeros.
    pub fn new(layout: BoardLayout) -> ReadBlockRepr {
        ReadBlockRepr {
            layout,
            timestamp: 0,
            status: StatusRead::default(),
            digital_in: DigitalIn::default(),
            temperature: Temperature::default(),
            motor: [MotorReading::default(); MAX_AXES],
            encoder: [EncoderReading::default(); MAX_AXES],
        }
    }

    /// The motors the layout has.
    #[inline]
    pub fn motors(&self) -> &[MotorReading] {
        self.motor.get(..self.layout.motors()).unwrap_or(&[])
    }

    /// The encoders the layout has.
    #[inline]
    pub fn encoders(&self) -> &[EncoderReading] {
        self.encoder.get(..self.layout.encoders()).unwrap_or(&[])
    }

    /// Parse a read block.
    ///
    /// # Errors
    /// Length errors of [`ReadBlock::check_len`].
    pub fn parse<T: AsRef<[u8]>>(block: &ReadBlock<T>) -> Result<ReadBlockRepr> {
        let mut repr = ReadBlockRepr::new(block.layout);
        repr.parse_into(block)?;
        Ok(repr)
    }

    /// Parse a read block into `self`, which then equals what
    /// [`parse`](Self::parse) returns (layout included), without a new
    /// block built and moved: the host's cycle parses every board's block
    /// in place (always inlined there: `#[inline]` alone left it a call
    /// across the crate boundary). On an error `self` is left as it was.
    ///
    /// # Errors
    /// Length errors of [`ReadBlock::check_len`].
    #[inline(always)]
    pub fn parse_into<T: AsRef<[u8]>>(&mut self, block: &ReadBlock<T>) -> Result<()> {
        block.check_len()?;
        let layout = block.layout;
        self.layout = layout;
        self.timestamp = block.timestamp();
        self.status = block.status();
        self.digital_in = block.digital_in();
        self.temperature = block.temperature();
        // Each section read straight from its start (worked out once): the
        // length check above guarantees every quadlet of the layout is in
        // the buffer. Slots beyond the layout's axes, and the sections the
        // layout lacks, read 0. The QLA1 at Rev 7 and 8 and the DQLA at Rev
        // 8 from quadlets at places known when compiling.
        let bytes = block.as_bytes();
        let filled = match (layout.format(), layout.motors(), layout.encoders()) {
            (BlockFormat::Rev8, 4, 4) => self.fill_from::<4, 32>(bytes),
            (BlockFormat::Rev7, 4, 4) => self.fill_from::<4, 28>(bytes),
            (BlockFormat::Rev8, 8, 8) => self.fill_from::<8, 60>(bytes),
            _ => false,
        };
        if !filled {
            self.fill_sections_any(bytes, layout);
        }
        Ok(())
    }

    /// [`parse_into`](Self::parse_into)'s sections from the first `Q`
    /// quadlets of `bytes`, a Rev 7 or 8 block with `N` motors and `N`
    /// encoders (MOTOR_STATUS when `Q` holds it); false, nothing written,
    /// when `bytes` is shorter. Each quadlet read straight into its field
    /// (the places are constants here: no copy of the block first).
    #[inline(always)]
    fn fill_from<const N: usize, const Q: usize>(&mut self, bytes: &[u8]) -> bool {
        let Some(bytes) = bytes.get(..Q * 4) else {
            return false;
        };
        let at = |q: usize| bytes.get(q * 4..q * 4 + 4).map_or(0, be_quadlet);
        let adc = field::READ_FIXED_QUADLETS;
        let encoders = adc + N;
        let status = encoders + 5 * N;
        let with_status = status + N <= Q;
        for (i, slot) in self.motor.iter_mut().enumerate() {
            *slot = if i < N {
                MotorReading {
                    adc: AdcWord(at(adc + i)),
                    status: MotorStatus(if with_status { at(status + i) } else { 0 }),
                }
            } else {
                MotorReading::default()
            };
        }
        for (i, slot) in self.encoder.iter_mut().enumerate() {
            let q = encoders + i;
            *slot = if i < N {
                EncoderReading {
                    position: EncPosition(at(q)),
                    period: EncPeriod(at(q + N)),
                    qtr1: EncQuarter(at(q + 2 * N)),
                    qtr5: EncQuarter(at(q + 3 * N)),
                    run: EncRun(at(q + 4 * N)),
                }
            } else {
                EncoderReading::default()
            };
        }
        true
    }

    /// [`parse_into`](Self::parse_into)'s sections for any layout.
    fn fill_sections_any(&mut self, bytes: &[u8], layout: BoardLayout) {
        let section = |(start, count): (usize, usize)| {
            let quadlets = bytes.get(start * 4..(start + count) * 4);
            quadlets.unwrap_or_default().chunks_exact(4).map(be_quadlet)
        };
        // Each section's quadlets into one field of each axis.
        type Set<T> = fn(&mut T, u32);
        fn fill<T>(slots: &mut [T], quadlets: impl Iterator<Item = u32>, set: Set<T>) {
            for (slot, q) in slots.iter_mut().zip(quadlets) {
                set(slot, q);
            }
        }
        let motor_fields: [(Section, Set<MotorReading>); 2] = [
            (Section::Adc, |m, q| m.adc = AdcWord(q)),
            (Section::MotorStatus, |m, q| m.status = MotorStatus(q)),
        ];
        let encoder_fields: [(Section, Set<EncoderReading>); 5] = [
            (Section::EncPosition, |e, q| e.position = EncPosition(q)),
            (Section::EncPeriod, |e, q| e.period = EncPeriod(q)),
            (Section::EncQtr1, |e, q| e.qtr1 = EncQuarter(q)),
            (Section::EncQtr5, |e, q| e.qtr5 = EncQuarter(q)),
            (Section::EncRun, |e, q| e.run = EncRun(q)),
        ];
        self.motor = [MotorReading::default(); MAX_AXES];
        for (s, set) in motor_fields {
            fill(&mut self.motor, section(layout.section(s)), set);
        }
        self.encoder = [EncoderReading::default(); MAX_AXES];
        for (s, set) in encoder_fields {
            fill(&mut self.encoder, section(layout.section(s)), set);
        }
    }

    /// Bytes [`emit`](Self::emit) writes.
    #[inline]
    pub fn buffer_len(&self) -> usize {
        self.layout.read_block_len()
    }

    /// Write the block into the start of `buf`; returns bytes written.
    ///
    /// # Errors
    /// [`Error::BufferTooSmall`].
    #[inline]
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize> {
        let len = self.buffer_len();
        let available = buf.len();
        let Some(out) = buf.get_mut(..len) else {
            return Err(Error::BufferTooSmall {
                what: "real-time read block",
                needed: len,
                available,
            });
        };
        let mut block = ReadBlock::new_unchecked(out, self.layout);
        block.set_timestamp(self.timestamp);
        block.set_status(self.status);
        block.set_digital_in(self.digital_in);
        block.set_temperature(self.temperature);
        for (i, m) in self.motors().iter().enumerate() {
            block.set_adc(i, m.adc)?;
            if self.layout.format() == BlockFormat::Rev8 {
                block.set_motor_status(i, m.status)?;
            }
        }
        let all_sections = self.layout.encoder_sections() == 5;
        for (i, e) in self.encoders().iter().enumerate() {
            block.set_enc_position(i, e.position)?;
            if all_sections {
                block.set_enc_period(i, e.period)?;
                block.set_enc_qtr1(i, e.qtr1)?;
                block.set_enc_qtr5(i, e.qtr5)?;
                block.set_enc_run(i, e.run)?;
            }
        }
        Ok(len)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const REV4: BoardLayout = BoardLayout::qla1(FirmwareRev::Rev4);
    const REV7: BoardLayout = BoardLayout::qla1(FirmwareRev::Rev7);
    const REV8: BoardLayout = BoardLayout::qla1(FirmwareRev::Rev8);
    const DQLA8: BoardLayout = BoardLayout::dqla(FirmwareRev::Rev8);

    #[test]
    fn set_axis_writes_what_the_setters_write() {
        let odd = BoardLayout::new(FirmwareRev::Rev8, 2, 3).unwrap();
        for layout in [REV4, REV7, REV8, DQLA8, odd] {
            let mut one = [0xA5u8; 256];
            let mut each = [0xA5u8; 256];
            for axis in 0..layout.motors().min(layout.encoders()) {
                let n = axis as u32 * 16;
                let motor = MotorReading {
                    adc: AdcWord(0x1000 + n),
                    status: MotorStatus(0x2000 + n),
                };
                let encoder = EncoderReading {
                    position: EncPosition(0x3000 + n),
                    period: EncPeriod(0x4000 + n),
                    qtr1: EncQuarter(0x5000 + n),
                    qtr5: EncQuarter(0x6000 + n),
                    run: EncRun(0x7000 + n),
                };
                let mut a = ReadBlock::new_unchecked(&mut one[..], layout);
                a.set_axis(axis, motor, encoder).unwrap();
                let mut b = ReadBlock::new_unchecked(&mut each[..], layout);
                b.set_adc(axis, motor.adc).unwrap();
                b.set_enc_position(axis, encoder.position).unwrap();
                if layout.format() != BlockFormat::Rev4 {
                    b.set_enc_period(axis, encoder.period).unwrap();
                    b.set_enc_qtr1(axis, encoder.qtr1).unwrap();
                    b.set_enc_qtr5(axis, encoder.qtr5).unwrap();
                    b.set_enc_run(axis, encoder.run).unwrap();
                }
                if layout.format() == BlockFormat::Rev8 {
                    b.set_motor_status(axis, motor.status).unwrap();
                }
            }
            assert_eq!(one, each, "{layout:?}");
            let beyond = layout.motors().min(layout.encoders());
            let mut block = ReadBlock::new_unchecked(&mut one[..], layout);
            let none = (MotorReading::default(), EncoderReading::default());
            assert!(block.set_axis(beyond, none.0, none.1).is_err());
        }
    }

    /// A QLA1 Rev 8 block whose quadlet i holds `0x0100_0000 * i + i`.
    fn numbered(layout: BoardLayout) -> [u8; 256] {
        let mut buf = [0xA5u8; 256];
        for q in 0..layout.read_block_quadlets() {
            write_quadlet(&mut buf, q, 0x0100_0000 * q as u32 + q as u32);
        }
        buf
    }

    #[test]
    fn read_block_sections_in_wire_order() {
        let buf = numbered(REV8);
        let block = ReadBlock::new_checked(&buf[..128], REV8).unwrap();
        let q = |i: u32| 0x0100_0000 * i + i;
        assert_eq!(block.timestamp(), q(0));
        assert_eq!(block.status().raw(), q(1));
        assert_eq!(block.digital_in().raw(), q(2));
        assert_eq!(block.temperature().raw(), q(3));
        assert_eq!(block.adc(0).unwrap().raw(), q(4));
        assert_eq!(block.adc(3).unwrap().raw(), q(7));
        assert_eq!(block.enc_position(0).unwrap().raw(), q(8));
        assert_eq!(block.enc_period(0).unwrap().raw(), q(12));
        assert_eq!(block.enc_qtr1(0).unwrap().raw(), q(16));
        assert_eq!(block.enc_qtr5(0).unwrap().raw(), q(20));
        assert_eq!(block.enc_run(3).unwrap().raw(), q(27));
        assert_eq!(block.motor_status(0).unwrap().raw(), q(28));
        assert_eq!(block.motor_status(3).unwrap().raw(), q(31));
        assert_eq!(block.adc(4), None);
        assert_eq!(block.motor_status(4), None);
        let buf7 = numbered(REV7);
        let block7 = ReadBlock::new_checked(&buf7[..112], REV7).unwrap();
        assert_eq!(block7.enc_run(3).unwrap().raw(), q(27));
        assert_eq!(block7.motor_status(0), None);
    }

    #[test]
    fn read_block_length_is_exact() {
        let buf = [0u8; 256];
        assert!(matches!(
            ReadBlock::new_checked(&buf[..124], REV8),
            Err(Error::BlockSize {
                expected: 32,
                found: 31,
                ..
            })
        ));
        assert!(matches!(
            ReadBlock::new_checked(&buf[..129], REV8),
            Err(Error::NotQuadletAligned { len: 129, .. })
        ));
        assert!(ReadBlock::new_checked(&buf[..240], DQLA8).is_ok());
    }

    #[test]
    fn read_block_round_trip_over_a5() {
        for layout in [REV4, REV7, REV8, DQLA8] {
            let buf = numbered(layout);
            let len = layout.read_block_len();
            let block = ReadBlock::new_checked(&buf[..len], layout).unwrap();
            let repr = ReadBlockRepr::parse(&block).unwrap();
            let mut out = [0xA5u8; 256];
            assert_eq!(repr.emit(&mut out), Ok(len));
            assert_eq!(&out[..len], &buf[..len]);
            assert!(out[len..].iter().all(|&b| b == 0xA5));
            assert_eq!(repr.motors().len(), layout.motors());
            assert_eq!(repr.encoders().len(), layout.encoders());
        }
        let repr = ReadBlockRepr::new(REV8);
        assert!(matches!(
            repr.emit(&mut [0u8; 64]),
            Err(Error::BufferTooSmall { needed: 128, .. })
        ));
    }

    #[test]
    fn read_block_setters_check_the_index() {
        let mut buf = [0u8; 112];
        let mut block = ReadBlock::new_checked(&mut buf[..], REV7).unwrap();
        assert!(block.set_adc(3, AdcWord(1)).is_ok());
        assert_eq!(
            block.set_adc(4, AdcWord(1)),
            Err(Error::Index {
                what: "ADC (motor)",
                index: 4,
                count: 4
            })
        );
        assert!(matches!(
            block.set_motor_status(0, MotorStatus(1)),
            Err(Error::Index { count: 0, .. })
        ));
    }

    /// Seed 000's sizes: 48 bytes read, 16 written, 13-quadlet broadcasts.
    #[test]
    fn rev4_blocks_have_seed_000_sizes_and_sections() {
        assert_eq!(FirmwareRev::from(4).block_format(), BlockFormat::Rev4);
        assert_eq!(REV4.read_block_len(), 48);
        assert_eq!(REV4.write_block_len(), 16);
        assert_eq!(REV4.broadcast_quadlets(), 13);
        let buf = numbered(REV4);
        let block = ReadBlock::new_checked(&buf[..48], REV4).unwrap();
        let q = |i: u32| 0x0100_0000 * i + i;
        assert_eq!(block.adc(3).unwrap().raw(), q(7));
        assert_eq!(block.enc_position(0).unwrap().raw(), q(8));
        assert_eq!(block.enc_position(3).unwrap().raw(), q(11));
        assert_eq!(block.enc_period(0), None);
        assert_eq!(block.enc_run(3), None);
        assert_eq!(block.motor_status(0), None);
        let repr = ReadBlockRepr::parse(&block).unwrap();
        assert_eq!(repr.encoder[1].position.raw(), q(9));
        assert_eq!(repr.encoder[1].period.raw(), 0);
        // Write block: four DAC quadlets naming the board, no control.
        let mut w = WriteBlockRepr::new(REV4, 5);
        w.dac[2] = DacWord::valid_command(0x1234);
        w.control = StatusWrite(0x0000_0F0F);
        let mut out = [0xA5u8; 20];
        assert_eq!(w.emit(&mut out), Ok(16));
        assert_eq!(read_quadlet(&out, 0), 0x0500_0000);
        assert_eq!(read_quadlet(&out, 2), 0x8500_1234);
        assert!(out[16..].iter().all(|&b| b == 0xA5));
        let view = WriteBlock::new_checked(&out[..16], REV4).unwrap();
        assert_eq!((view.board_id(), view.header()), (5, None));
        assert_eq!(view.control(), StatusWrite::default());
        let parsed = WriteBlockRepr::parse(&view).unwrap();
        assert_eq!(parsed.dac[2].command(), 0x1234);
        assert_eq!(parsed.control, StatusWrite::default());
    }
}
