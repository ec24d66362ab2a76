//! Firmware revisions, board layouts and the real-time blocks: the block
//! read and block write of address 0 (`fpga-board.md` §4, §5).
//!
//! Two tiers per block, as for packets: a checked view over bytes
//! ([`ReadBlock`], [`WriteBlock`]) and a meaning type with fixed arrays of
//! [`MAX_AXES`] entries ([`ReadBlockRepr`], [`WriteBlockRepr`]).
//!
//! # Panics
//! After [`ReadBlock::new_checked`] / [`WriteBlock::new_checked`] (or a
//! successful `check_len`) no accessor panics; per-axis accessors return
//! `None` (getters) or [`Error::Index`] (setters) for an axis the layout
//! does not have. Unchecked views read 0 where bytes are missing.
//!
//! ```
//! use firelink_wire::board::realtime::{BoardLayout, FirmwareRev, ReadBlock, ReadBlockRepr};
//! use firelink_wire::board::registers::EncPosition;
//! let layout = BoardLayout::qla1(FirmwareRev::Rev8);
//! let mut repr = ReadBlockRepr::new(layout);
//! repr.encoder[2].position = EncPosition::default().with_counts(-5).unwrap();
//! let mut buf = [0u8; 128];
//! let len = repr.emit(&mut buf).unwrap();
//! assert_eq!(len, 32 * 4);
//! let view = ReadBlock::new_checked(&buf[..len], layout).unwrap();
//! assert_eq!(view.enc_position(2).unwrap().counts(), -5);
//! assert_eq!(ReadBlockRepr::parse(&view).unwrap(), repr);
//! ```

use crate::board::address::check_board_id;
use crate::board::registers::{
    AdcWord, DacWord, DigitalIn, EncPeriod, EncPosition, EncQuarter, EncRun, HardwareVersion,
    MotorStatus, StatusRead, StatusWrite, Temperature,
};
use crate::board::{MAX_AXES, layout_view};
use crate::error::{Error, Result};
use crate::field::{read_quadlet, write_quadlet};
use crate::open_enum::open_enum;

/// Fixed quadlets of the blocks (`fpga-board.md` §4, §5), each defined once.
mod field {
    use crate::field::Field;

    /// Read block: 49.152 MHz clocks since the previous read.
    pub const TIMESTAMP: Field = Field::quadlet(0);
    /// Read block: STATUS.
    pub const STATUS: Field = Field::quadlet(1);
    /// Read block: DIGITAL_IN.
    pub const DIGITAL_IN: Field = Field::quadlet(2);
    /// Read block: TEMPERATURE.
    pub const TEMPERATURE: Field = Field::quadlet(3);
    /// Read block: quadlets before the per-axis sections.
    pub const READ_FIXED_QUADLETS: usize = 4;

    /// Rev 8 write block header: everything above the board ID must be 0.
    pub const HEADER_RESERVED: Field = Field::new(0, 31, 16);
    /// Rev 8 write block header: the board ID, bits 15:8.
    pub const HEADER_BOARD_ID: Field = Field::new(0, 15, 8);
    /// Rev 8 write block header: quadlets of the block including the
    /// header (`motors + 2`), bits 7:0.
    pub const HEADER_QUADLETS: Field = Field::new(0, 7, 0);
}

open_enum! {
    /// Firmware revision, as FW_VERSION reads (`fpga-board.md` §2). Open:
    /// later revisions are data and use the newest known block format.
    pub enum FirmwareRev(u32) {
        /// Rev 4, the firmware of seed 000's era: the first broadcast
        /// firmware (fixed TDMA slots). Seed 000 states only its block
        /// sizes (48 bytes read and 16 bytes written per QLA board); the
        /// layout assumed here is the first sections of Rev 7's
        /// ([`BlockFormat::Rev4`]).
        Rev4 = 4,
        /// Rev 7: no MOTOR_STATUS block, write block without header.
        Rev7 = 7,
        /// Rev 8: MOTOR_STATUS block, write block with a header.
        Rev8 = 8,
        /// Rev 9: the same block layouts as Rev 8 (`rev9-fpga-v3.md`);
        /// GIT_DESC in register 15, the FPGA V3 Ethernet-only network.
        Rev9 = 9,
    }
}

/// The layout family of the real-time blocks and hub headers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum BlockFormat {
    /// Rev 4, seed 000's era (an assumption: seed 000 gives the sizes,
    /// not the layout): the read block is Rev 7's fixed quadlets, one ADC
    /// quadlet per motor and one ENC_POSITION per encoder (`4 + M + E`, 12
    /// for a QLA: the 48 bytes of seed 000's sequential read); the write
    /// block is one DAC quadlet per motor, board ID in bits 27:24 as on
    /// Rev 7, with no control quadlet (16 bytes for a QLA, seed 000
    /// Fig. 10a); hub entries carry Rev 7 headers and no timing quadlet
    /// follows them.
    Rev4,
    /// Rev 7 (`fpga-board.md` §4, §5, §6.3).
    Rev7,
    /// Rev 8 (`fpga-board.md` §4, §5, §6.3).
    Rev8,
}

impl FirmwareRev {
    /// The revision number.
    #[inline]
    pub fn number(self) -> u32 {
        u32::from(self)
    }

    /// The block format of this revision: Rev 8 and later use the Rev 8
    /// format, Rev 4 its own; other earlier revisions (which the spec does
    /// not describe) the Rev 7 format.
    #[inline]
    pub fn block_format(self) -> BlockFormat {
        // (The named revisions without turning them into numbers first:
        // every cycle asks, several times per board.)
        match self {
            FirmwareRev::Rev8 | FirmwareRev::Rev9 => BlockFormat::Rev8,
            FirmwareRev::Rev7 => BlockFormat::Rev7,
            FirmwareRev::Rev4 => BlockFormat::Rev4,
            FirmwareRev::Unknown(n) if n >= 8 => BlockFormat::Rev8,
            FirmwareRev::Unknown(4) => BlockFormat::Rev4,
            FirmwareRev::Unknown(_) => BlockFormat::Rev7,
        }
    }
}

/// Which real-time block layout a board has: firmware revision and the
/// number of motors and encoders (`fpga-board.md` §4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct BoardLayout {
    firmware: FirmwareRev,
    motors: u8,
    encoders: u8,
}

/// The per-axis sections of the read block, in wire order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Section {
    Adc,
    EncPosition,
    EncPeriod,
    EncQtr1,
    EncQtr5,
    EncRun,
    MotorStatus,
}

impl Section {
    fn name(self) -> &'static str {
        match self {
            Section::Adc => "ADC (motor)",
            Section::EncPosition => "ENC_POSITION (encoder)",
            Section::EncPeriod => "ENC_PERIOD (encoder)",
            Section::EncQtr1 => "ENC_QTR1 (encoder)",
            Section::EncQtr5 => "ENC_QTR5 (encoder)",
            Section::EncRun => "ENC_RUN (encoder)",
            Section::MotorStatus => "MOTOR_STATUS (motor, Rev 8)",
        }
    }
}

impl BoardLayout {
    /// A QLA1 board: 4 motors, 4 encoders.
    #[inline]
    pub const fn qla1(firmware: FirmwareRev) -> BoardLayout {
        BoardLayout {
            firmware,
            motors: 4,
            encoders: 4,
        }
    }

    /// A DQLA board: 8 motors, 8 encoders.
    #[inline]
    pub const fn dqla(firmware: FirmwareRev) -> BoardLayout {
        BoardLayout {
            firmware,
            motors: 8,
            encoders: 8,
        }
    }

    /// Any layout.
    ///
    /// # Errors
    /// [`Error::OutOfRange`] unless 1 <= motors, encoders <= [`MAX_AXES`].
    #[inline]
    pub fn new(firmware: FirmwareRev, motors: u8, encoders: u8) -> Result<BoardLayout> {
        for (what, n) in [("motors", motors), ("encoders", encoders)] {
            if n == 0 || usize::from(n) > MAX_AXES {
                return Err(Error::OutOfRange {
                    what,
                    value: i64::from(n),
                    min: 1,
                    max: MAX_AXES as i64,
                });
            }
        }
        Ok(BoardLayout {
            firmware,
            motors,
            encoders,
        })
    }

    /// The layout of a known companion board (QLA1, DQLA); `None` otherwise.
    #[inline]
    pub fn for_hardware(hardware: HardwareVersion, firmware: FirmwareRev) -> Option<BoardLayout> {
        match hardware {
            HardwareVersion::Qla1 => Some(Self::qla1(firmware)),
            HardwareVersion::Dqla => Some(Self::dqla(firmware)),
            _ => None,
        }
    }

    /// The firmware revision.
    #[inline]
    pub const fn firmware(self) -> FirmwareRev {
        self.firmware
    }

    /// The block format of the firmware.
    #[inline]
    pub fn format(self) -> BlockFormat {
        self.firmware.block_format()
    }

    /// Number of motors (ADC, DAC and MOTOR_STATUS entries).
    #[inline]
    pub const fn motors(self) -> usize {
        self.motors as usize
    }

    /// Number of encoders.
    #[inline]
    pub const fn encoders(self) -> usize {
        self.encoders as usize
    }

    /// Encoder sections of the read block: ENC_POSITION only on Rev 4,
    /// all five (position, period, QTR1, QTR5, run) later.
    #[inline]
    fn encoder_sections(self) -> usize {
        match self.format() {
            BlockFormat::Rev4 => 1,
            BlockFormat::Rev7 | BlockFormat::Rev8 => 5,
        }
    }

    /// Start quadlet and entry count of a section (0 entries: the layout
    /// has no such section).
    #[inline]
    fn section(self, section: Section) -> (usize, usize) {
        let m = self.motors();
        let e = self.encoders();
        let encoder_start = field::READ_FIXED_QUADLETS + m;
        let sections = self.encoder_sections();
        let encoder = |k: usize| {
            if k < sections {
                (encoder_start + k * e, e)
            } else {
                (encoder_start + sections * e, 0)
            }
        };
        match section {
            Section::Adc => (field::READ_FIXED_QUADLETS, m),
            Section::EncPosition => encoder(0),
            Section::EncPeriod => encoder(1),
            Section::EncQtr1 => encoder(2),
            Section::EncQtr5 => encoder(3),
            Section::EncRun => encoder(4),
            Section::MotorStatus => match self.format() {
                BlockFormat::Rev4 | BlockFormat::Rev7 => (encoder_start + sections * e, 0),
                BlockFormat::Rev8 => (encoder_start + sections * e, m),
            },
        }
    }

    /// The quadlet of entry `index` of a section, or the error naming it.
    #[inline]
    fn quadlet(self, section: Section, index: usize) -> Result<usize> {
        let (start, count) = self.section(section);
        if index < count {
            Ok(start + index)
        } else {
            Err(Error::Index {
                what: section.name(),
                index,
                count,
            })
        }
    }

    /// Quadlets of the real-time read block: Rev 7 `4 + M + 5E` (QLA1 28),
    /// Rev 8 `4 + 2M + 5E` (QLA1 32, DQLA 60), `fpga-board.md` §4; Rev 4
    /// `4 + M + E` (QLA1 12).
    #[inline]
    pub fn read_block_quadlets(self) -> usize {
        let (start, count) = self.section(Section::MotorStatus);
        start + count
    }

    /// Bytes of the real-time read block.
    #[inline]
    pub fn read_block_len(self) -> usize {
        self.read_block_quadlets() * 4
    }

    /// Quadlets of the real-time write block: Rev 8 `1 + M + 1` (QLA1 6),
    /// Rev 7 `M + 1` (QLA1 5), `fpga-board.md` §5; Rev 4 `M` (QLA1 4).
    #[inline]
    pub fn write_block_quadlets(self) -> usize {
        match self.format() {
            BlockFormat::Rev4 => self.motors(),
            BlockFormat::Rev7 => self.motors() + 1,
            BlockFormat::Rev8 => self.motors() + 2,
        }
    }

    /// Bytes of the real-time write block.
    #[inline]
    pub fn write_block_len(self) -> usize {
        self.write_block_quadlets() * 4
    }

    /// Quadlets of one status broadcast: header plus read block
    /// (`fpga-board.md` §6.2: QLA1 Rev 8 33, Rev 7 29).
    #[inline]
    pub fn broadcast_quadlets(self) -> usize {
        self.read_block_quadlets() + 1
    }
}

// ------------------------------------------------------------ Read block ---

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

/// The first `Q` quadlets of `bytes`, if it holds them.
#[inline]
fn words<const Q: usize>(bytes: &[u8]) -> Option<[u32; Q]> {
    let mut out = [0; Q];
    let bytes = bytes.get(..Q * 4)?;
    for (o, q) in out.iter_mut().zip(bytes.chunks_exact(4)) {
        *o = be_quadlet(q);
    }
    Some(out)
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
    /// in place. On an error `self` is left as it was.
    ///
    /// # Errors
    /// Length errors of [`ReadBlock::check_len`].
    #[inline]
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
            (BlockFormat::Rev8, 4, 4) => words::<32>(bytes).map(|w| self.fill_from::<4, 32>(&w)),
            (BlockFormat::Rev7, 4, 4) => words::<28>(bytes).map(|w| self.fill_from::<4, 28>(&w)),
            (BlockFormat::Rev8, 8, 8) => words::<60>(bytes).map(|w| self.fill_from::<8, 60>(&w)),
            _ => None,
        };
        if filled.is_none() {
            self.fill_sections_any(bytes, layout);
        }
        Ok(())
    }

    /// [`parse_into`](Self::parse_into)'s sections from the `Q` quadlets
    /// of a Rev 7 or 8 block with `N` motors and `N` encoders (MOTOR_STATUS
    /// when `Q` holds it).
    #[inline]
    fn fill_from<const N: usize, const Q: usize>(&mut self, words: &[u32; Q]) {
        let at = |q: usize| words.get(q).copied().unwrap_or(0);
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

// ----------------------------------------------------------- Write block ---

/// The header quadlet of a Rev 8 write block: `(board_id<<8) | (motors+2)`
/// (`fpga-board.md` §5).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct WriteHeader {
    /// The board the block is for (bits 15:8).
    pub board_id: u8,
    /// Quadlets of the block including this header (bits 7:0).
    pub quadlets: u8,
}

impl WriteHeader {
    /// Decode a header quadlet (bits 31:16 are ignored).
    pub fn from_word(word: u32) -> WriteHeader {
        WriteHeader {
            board_id: field::HEADER_BOARD_ID.extract(word) as u8,
            quadlets: field::HEADER_QUADLETS.extract(word) as u8,
        }
    }

    /// Encode as the header quadlet.
    pub fn to_word(self) -> u32 {
        let w = field::HEADER_BOARD_ID.insert(0, u32::from(self.board_id));
        field::HEADER_QUADLETS.insert(w, u32::from(self.quadlets))
    }
}

layout_view! {
    /// A checked view of a real-time write block (`fpga-board.md` §5).
    pub struct WriteBlock;
    what: "real-time write block",
    quadlets: write_block_quadlets,
}

impl<T: AsRef<[u8]>> WriteBlock<T> {
    fn dac_quadlet(&self) -> usize {
        match self.layout.format() {
            BlockFormat::Rev4 | BlockFormat::Rev7 => 0,
            BlockFormat::Rev8 => 1,
        }
    }

    /// The Rev 8 header; `None` on Rev 4 and Rev 7 (no header).
    pub fn header(&self) -> Option<WriteHeader> {
        match self.layout.format() {
            BlockFormat::Rev4 | BlockFormat::Rev7 => None,
            BlockFormat::Rev8 => Some(WriteHeader::from_word(read_quadlet(
                self.buffer.as_ref(),
                0,
            ))),
        }
    }

    /// The board the block is for: header bits 15:8 on Rev 8, the first DAC
    /// quadlet's bits 27:24 on Rev 4 and Rev 7.
    pub fn board_id(&self) -> u8 {
        match self.header() {
            Some(h) => h.board_id,
            None => self.dac(0).map_or(0, DacWord::board_id),
        }
    }

    /// The DAC quadlet of 0-based `motor`.
    pub fn dac(&self, motor: usize) -> Option<DacWord> {
        (motor < self.layout.motors()).then(|| {
            DacWord(read_quadlet(
                self.buffer.as_ref(),
                self.dac_quadlet() + motor,
            ))
        })
    }

    /// The control quadlet, written to STATUS (only bits 19:0 take effect:
    /// see [`StatusWrite::block_command`]); Rev 4 blocks have none and read
    /// the zero word, which changes nothing.
    pub fn control(&self) -> StatusWrite {
        match self.layout.format() {
            BlockFormat::Rev4 => StatusWrite::default(),
            BlockFormat::Rev7 | BlockFormat::Rev8 => {
                let q = self.layout.write_block_quadlets().saturating_sub(1);
                StatusWrite(read_quadlet(self.buffer.as_ref(), q))
            }
        }
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> WriteBlock<T> {
    /// Set the Rev 8 header.
    ///
    /// # Errors
    /// [`Error::InvalidValue`] on Rev 4 and Rev 7, whose blocks have no
    /// header.
    pub fn set_header(&mut self, header: WriteHeader) -> Result<()> {
        match self.layout.format() {
            BlockFormat::Rev4 | BlockFormat::Rev7 => Err(Error::InvalidValue {
                what: "firmware revision for a write block header (Rev 4 and 7 blocks have none)",
                value: self.layout.firmware().number(),
            }),
            BlockFormat::Rev8 => {
                write_quadlet(self.buffer.as_mut(), 0, header.to_word());
                Ok(())
            }
        }
    }

    /// Set the DAC quadlet of 0-based `motor`.
    ///
    /// # Errors
    /// [`Error::Index`] for a motor the layout does not have.
    pub fn set_dac(&mut self, motor: usize, dac: DacWord) -> Result<()> {
        let count = self.layout.motors();
        if motor >= count {
            return Err(Error::Index {
                what: "DAC (motor)",
                index: motor,
                count,
            });
        }
        let q = self.dac_quadlet() + motor;
        write_quadlet(self.buffer.as_mut(), q, dac.0);
        Ok(())
    }

    /// Set the control quadlet (Rev 4 blocks have none: nothing is written).
    pub fn set_control(&mut self, control: StatusWrite) {
        if self.layout.format() == BlockFormat::Rev4 {
            return;
        }
        let q = self.layout.write_block_quadlets().saturating_sub(1);
        write_quadlet(self.buffer.as_mut(), q, control.0);
    }
}

/// The meaning of a real-time write block (`fpga-board.md` §5).
///
/// On Rev 4 and Rev 7 the board ID travels in bits 27:24 of every DAC
/// quadlet (and Rev 4 has no control quadlet: `control` is not on the wire):
/// [`emit`](Self::emit) writes it there, [`parse`](Self::parse) keeps the DAC
/// quadlets raw (so they carry it) and checks they agree.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct WriteBlockRepr {
    /// The layout.
    pub layout: BoardLayout,
    /// The board the block is for, 0..=15.
    pub board_id: u8,
    /// DAC quadlets, index 0 = motor 1; entries beyond the layout's motors
    /// are not on the wire.
    pub dac: [DacWord; MAX_AXES],
    /// The control quadlet, written to STATUS.
    pub control: StatusWrite,
}

impl WriteBlockRepr {
    /// A block for `board_id` with all DAC quadlets and the control zero.
    pub fn new(layout: BoardLayout, board_id: u8) -> WriteBlockRepr {
        WriteBlockRepr {
            layout,
            board_id,
            dac: [DacWord::default(); MAX_AXES],
            control: StatusWrite::default(),
        }
    }

    /// The DAC quadlets of the layout's motors.
    #[inline]
    pub fn dacs(&self) -> &[DacWord] {
        self.dac.get(..self.layout.motors()).unwrap_or(&[])
    }

    /// Parse a write block.
    ///
    /// # Errors
    /// Length errors of [`WriteBlock::check_len`]; on Rev 8
    /// [`Error::Malformed`] for a header with bits 31:16 set or a board ID
    /// above 15 and [`Error::BlockSize`] when its length is not the
    /// layout's; on Rev 4 and Rev 7 [`Error::Malformed`] when the DAC quadlets
    /// disagree on the board ID.
    pub fn parse<T: AsRef<[u8]>>(block: &WriteBlock<T>) -> Result<WriteBlockRepr> {
        block.check_len()?;
        let layout = block.layout;
        let board_id = block.board_id();
        if layout.format() == BlockFormat::Rev8 {
            let word = read_quadlet(block.as_bytes(), 0);
            if field::HEADER_RESERVED.extract(word) != 0 || check_board_id(board_id).is_err() {
                return Err(Error::Malformed {
                    what: "Rev 8 write block header",
                    value: word,
                });
            }
            let declared = usize::from(WriteHeader::from_word(word).quadlets);
            if declared != layout.write_block_quadlets() {
                return Err(Error::BlockSize {
                    what: "Rev 8 write block (header length)",
                    expected: layout.write_block_quadlets(),
                    found: declared,
                });
            }
        }
        let mut repr = WriteBlockRepr::new(layout, board_id);
        for (i, d) in repr.dac.iter_mut().enumerate() {
            let Some(dac) = block.dac(i) else { break };
            if layout.format() != BlockFormat::Rev8 && dac.board_id() != board_id {
                return Err(Error::Malformed {
                    what: "Rev 4/7 write block DAC quadlet with another board ID",
                    value: dac.0,
                });
            }
            *d = dac;
        }
        repr.control = block.control();
        Ok(repr)
    }

    /// Bytes [`emit`](Self::emit) writes.
    #[inline]
    pub fn buffer_len(&self) -> usize {
        self.layout.write_block_len()
    }

    /// Write the block into the start of `buf`; returns bytes written.
    ///
    /// # Errors
    /// [`Error::FieldRange`] for a board ID above 15;
    /// [`Error::BufferTooSmall`].
    #[inline]
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize> {
        check_board_id(self.board_id)?;
        let len = self.buffer_len();
        let available = buf.len();
        let Some(out) = buf.get_mut(..len) else {
            return Err(Error::BufferTooSmall {
                what: "real-time write block",
                needed: len,
                available,
            });
        };
        // Whole quadlets in wire order (what `WriteBlock`'s setters write,
        // each once): the Rev 8 header, the DACs (Rev 4 and 7: with the
        // board ID), the control quadlet last (none on Rev 4).
        let format = self.layout.format();
        let mut quadlets = out.chunks_exact_mut(4);
        let mut put = |word: u32| {
            if let Some(q) = quadlets.next() {
                q.copy_from_slice(&word.to_be_bytes());
            }
        };
        if format == BlockFormat::Rev8 {
            put(WriteHeader {
                board_id: self.board_id,
                quadlets: self.layout.write_block_quadlets() as u8,
            }
            .to_word());
        }
        for &dac in self.dacs() {
            put(match format {
                BlockFormat::Rev4 | BlockFormat::Rev7 => dac.with_board_id(self.board_id).0,
                BlockFormat::Rev8 => dac.0,
            });
        }
        if format != BlockFormat::Rev4 {
            put(self.control.0);
        }
        Ok(len)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::board::registers::{DAC_ZERO, STATUS_POWER_ON, StatusCommand};

    const REV4: BoardLayout = BoardLayout::qla1(FirmwareRev::Rev4);
    const REV7: BoardLayout = BoardLayout::qla1(FirmwareRev::Rev7);
    const REV8: BoardLayout = BoardLayout::qla1(FirmwareRev::Rev8);
    const DQLA8: BoardLayout = BoardLayout::dqla(FirmwareRev::Rev8);

    /// The format by the revision's number, named or not.
    #[test]
    fn block_format_follows_the_number() {
        let by_number = |n: u32| match n {
            n if n >= 8 => BlockFormat::Rev8,
            4 => BlockFormat::Rev4,
            _ => BlockFormat::Rev7,
        };
        for n in (0..20).chain([u32::MAX]) {
            assert_eq!(FirmwareRev::from(n).block_format(), by_number(n), "{n}");
            assert_eq!(FirmwareRev::Unknown(n).block_format(), by_number(n), "{n}");
        }
    }

    /// `rev9-fpga-v3.md`: the real-time blocks of Rev 8 and Rev 9 are the
    /// same, read 4 + 2M + 5E quadlets (QLA1 32, DQLA 60), write M + 2
    /// (QLA1 6, DQLA 10).
    #[test]
    fn rev9_blocks_are_rev8_blocks() {
        for (rev, n) in [(FirmwareRev::Rev8, 8), (FirmwareRev::Rev9, 9)] {
            assert_eq!(rev.number(), n);
            assert_eq!(FirmwareRev::from(n), rev);
            let (q, d) = (BoardLayout::qla1(rev), BoardLayout::dqla(rev));
            assert_eq!(q.format(), BlockFormat::Rev8);
            assert_eq!((q.read_block_quadlets(), q.write_block_quadlets()), (32, 6));
            assert_eq!(
                (d.read_block_quadlets(), d.write_block_quadlets()),
                (60, 10)
            );
        }
    }

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

    #[test]
    fn block_sizes_from_the_spec() {
        assert_eq!(REV7.read_block_quadlets(), 28);
        assert_eq!(REV8.read_block_quadlets(), 32);
        assert_eq!(DQLA8.read_block_quadlets(), 60);
        assert_eq!(REV8.write_block_quadlets(), 6);
        assert_eq!(REV7.write_block_quadlets(), 5);
        assert_eq!(DQLA8.write_block_quadlets(), 10);
        assert_eq!(REV8.broadcast_quadlets(), 33);
        assert_eq!(REV7.broadcast_quadlets(), 29);
        assert_eq!(REV8.read_block_len(), 128);
        assert_eq!(
            BoardLayout::new(FirmwareRev::Rev8, 2, 3)
                .unwrap()
                .read_block_quadlets(),
            4 + 2 * 2 + 5 * 3
        );
        assert!(BoardLayout::new(FirmwareRev::Rev8, 0, 3).is_err());
        assert!(BoardLayout::new(FirmwareRev::Rev8, 2, 9).is_err());
        assert_eq!(FirmwareRev::from(9).block_format(), BlockFormat::Rev8);
        assert_eq!(FirmwareRev::from(5).block_format(), BlockFormat::Rev7);
        assert_eq!(
            BoardLayout::for_hardware(HardwareVersion::Dqla, FirmwareRev::Rev8),
            Some(DQLA8)
        );
        assert_eq!(
            BoardLayout::for_hardware(HardwareVersion::Dra1, FirmwareRev::Rev8),
            None
        );
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

    #[test]
    fn rev8_write_block_worked_example() {
        let mut repr = WriteBlockRepr::new(REV8, 3);
        for (i, d) in repr.dac.iter_mut().take(4).enumerate() {
            *d = DacWord::valid_command(DAC_ZERO + i as u16).with_amp_request(Some(true));
        }
        repr.control = StatusCommand::power(true).to_word();
        let mut buf = [0xA5u8; 32];
        assert_eq!(repr.emit(&mut buf), Ok(24));
        let expect: [u32; 6] = [
            0x0000_0306,
            0xB000_8000,
            0xB000_8001,
            0xB000_8002,
            0xB000_8003,
            STATUS_POWER_ON,
        ];
        for (i, &w) in expect.iter().enumerate() {
            assert_eq!(read_quadlet(&buf, i), w, "quadlet {i}");
        }
        assert!(buf[24..].iter().all(|&b| b == 0xA5));
        let block = WriteBlock::new_checked(&buf[..24], REV8).unwrap();
        assert_eq!(
            block.header(),
            Some(WriteHeader {
                board_id: 3,
                quadlets: 6
            })
        );
        assert_eq!(block.board_id(), 3);
        assert_eq!(WriteBlockRepr::parse(&block), Ok(repr));
    }

    #[test]
    fn rev7_write_block_carries_the_board_id_in_each_dac() {
        let mut repr = WriteBlockRepr::new(REV7, 9);
        repr.dac[0] = DacWord::valid_command(0x1234);
        repr.dac[3] = DacWord::valid_command(DAC_ZERO);
        repr.control = StatusWrite(0x0000_0F0F);
        let mut buf = [0xA5u8; 20];
        assert_eq!(repr.emit(&mut buf), Ok(20));
        assert_eq!(read_quadlet(&buf, 0), 0x8900_1234);
        assert_eq!(read_quadlet(&buf, 1), 0x0900_0000);
        assert_eq!(read_quadlet(&buf, 3), 0x8900_8000);
        assert_eq!(read_quadlet(&buf, 4), 0x0000_0F0F);
        let block = WriteBlock::new_checked(&buf[..], REV7).unwrap();
        assert_eq!(block.header(), None);
        assert_eq!(block.board_id(), 9);
        let parsed = WriteBlockRepr::parse(&block).unwrap();
        assert_eq!(parsed.board_id, 9);
        assert_eq!(parsed.dac[0].command(), 0x1234);
        let mut again = [0xA5u8; 20];
        parsed.emit(&mut again).unwrap();
        assert_eq!(again, buf);
        // A DAC naming another board.
        write_quadlet(&mut buf, 2, 0x8A00_0000);
        let block = WriteBlock::new_checked(&buf[..], REV7).unwrap();
        assert!(matches!(
            WriteBlockRepr::parse(&block),
            Err(Error::Malformed { .. })
        ));
    }

    #[test]
    fn write_block_errors() {
        let mut buf = [0u8; 24];
        write_quadlet(&mut buf, 0, 0x0000_0305);
        let block = WriteBlock::new_checked(&buf[..], REV8).unwrap();
        assert!(matches!(
            WriteBlockRepr::parse(&block),
            Err(Error::BlockSize {
                expected: 6,
                found: 5,
                ..
            })
        ));
        write_quadlet(&mut buf, 0, 0x0001_0306);
        let block = WriteBlock::new_checked(&buf[..], REV8).unwrap();
        assert!(matches!(
            WriteBlockRepr::parse(&block),
            Err(Error::Malformed { .. })
        ));
        assert!(WriteBlock::new_checked(&buf[..20], REV8).is_err());
        assert!(WriteBlockRepr::new(REV8, 16).emit(&mut buf).is_err());
        assert!(WriteBlockRepr::new(REV8, 1).emit(&mut buf[..20]).is_err());
        let mut rev7 = [0u8; 20];
        let mut view = WriteBlock::new_unchecked(&mut rev7[..], REV7);
        assert!(view.set_header(WriteHeader::from_word(0)).is_err());
        assert!(view.set_dac(4, DacWord(0)).is_err());
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
