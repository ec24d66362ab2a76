//! Firmware revisions and board layouts (`fpga-board.md` §4, §5): which block
//! format a firmware revision speaks, how many motors and encoders a board
//! carries, and from those the size and section offsets of its real-time read
//! and write blocks.

use super::*;

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
    pub const fn block_format(self) -> BlockFormat {
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
    /// `firmware.block_format()` and the read block's quadlets, worked out
    /// once when the layout is made: every cycle asks for both several
    /// times per board. (Functions of the three fields above, so equality
    /// and hashing mean the same with them.)
    format: BlockFormat,
    read_quadlets: u8,
}

/// The per-axis sections of the read block, in wire order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Section {
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
        Self::made(firmware, 4, 4)
    }

    /// A DQLA board: 8 motors, 8 encoders.
    #[inline]
    pub const fn dqla(firmware: FirmwareRev) -> BoardLayout {
        Self::made(firmware, 8, 8)
    }

    /// The layout with its derived fields, for counts already checked (at
    /// most [`MAX_AXES`] each: the read block is then at most
    /// `4 + 2 * 8 + 5 * 8 = 60` quadlets).
    const fn made(firmware: FirmwareRev, motors: u8, encoders: u8) -> BoardLayout {
        let format = firmware.block_format();
        let (m, e) = (motors as usize, encoders as usize);
        // Rev 4 `4 + M + E`, Rev 7 `4 + M + 5E`, Rev 8 `4 + 2M + 5E`
        // (`fpga-board.md` §4; what `section` gives, see the tests).
        let quadlets = field::READ_FIXED_QUADLETS
            + match format {
                BlockFormat::Rev4 => m + e,
                BlockFormat::Rev7 => m + 5 * e,
                BlockFormat::Rev8 => 2 * m + 5 * e,
            };
        BoardLayout {
            firmware,
            motors,
            encoders,
            format,
            read_quadlets: quadlets as u8,
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
        Ok(Self::made(firmware, motors, encoders))
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
    pub const fn format(self) -> BlockFormat {
        self.format
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
    pub(super) fn encoder_sections(self) -> usize {
        match self.format() {
            BlockFormat::Rev4 => 1,
            BlockFormat::Rev7 | BlockFormat::Rev8 => 5,
        }
    }

    /// Start quadlet and entry count of a section (0 entries: the layout
    /// has no such section).
    #[inline]
    pub(super) fn section(self, section: Section) -> (usize, usize) {
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
    pub(super) fn quadlet(self, section: Section, index: usize) -> Result<usize> {
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
    pub const fn read_block_quadlets(self) -> usize {
        self.read_quadlets as usize
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

#[cfg(test)]
mod tests {
    use super::*;

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

    /// The read block's size kept in the layout is where its last
    /// section ends, for every format and count.
    #[test]
    fn kept_read_quadlets_end_the_last_section() {
        for rev in (0..12).map(FirmwareRev::from) {
            for m in 1..=MAX_AXES as u8 {
                for e in 1..=MAX_AXES as u8 {
                    let l = BoardLayout::new(rev, m, e).unwrap();
                    let (start, count) = l.section(Section::MotorStatus);
                    assert_eq!(l.read_block_quadlets(), start + count, "{rev:?} {m} {e}");
                    assert_eq!(l.format(), rev.block_format());
                }
            }
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
}
