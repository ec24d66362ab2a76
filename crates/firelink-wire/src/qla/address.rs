//! Board addresses: address spaces, the main-space register map, hub and
//! broadcast offsets.
//!
//! Facts: `fpga-board.md` §1 (spaces), §2 (board registers), §3 (axis
//! registers), §6 (hub and broadcast offsets). Only the low 16 bits of the
//! 48-bit offset are decoded; bits 15:12 select the space. Offsets count
//! quadlets: the quadlets of a block read or write sit at consecutive
//! offsets (the hub memory's 512 quadlets are `0x1000..=0x11FF`).
//!
//! ```
//! use firelink_wire::qla::address::{Address, AddressSpace, AxisRegister, Register};
//! let reg = Register::axis(2, AxisRegister::EncPosition);
//! assert_eq!(reg.offset(), Ok(0x25));
//! assert_eq!(Register::from_offset(0x25), Some(reg));
//! assert_eq!(Address::from_offset(0xFFFF_FF00_1000).space, AddressSpace::Hub);
//! ```

use crate::error::{Error, Result};
use crate::open_enum::open_enum;
use crate::qla::{MAX_BOARD_ID, check_max};

/// Bit fields of the low 16 bits of an offset (`fpga-board.md` §1), each
/// defined once.
mod field {
    use crate::field::Field;

    /// The address space, bits 15:12.
    pub const SPACE: Field = Field::new(0, 15, 12);
    /// The address inside the space, bits 11:0.
    pub const INDEX: Field = Field::new(0, 11, 0);
    /// Main space: bits 11:8 are zero for every register.
    pub const MAIN_HIGH: Field = Field::new(0, 11, 8);
    /// Main space: the channel (0 = board, 1..N = axis), bits 7:4.
    pub const CHANNEL: Field = Field::new(0, 7, 4);
    /// Main space: the register offset in the channel, bits 3:0.
    pub const REGISTER: Field = Field::new(0, 3, 0);
}

/// The bits of a 48-bit offset the board decodes.
const DECODED_BITS: u64 = 0xFFFF;

open_enum! {
    /// Address space, bits 15:12 of the offset (`fpga-board.md` §1).
    pub enum AddressSpace(u8) {
        /// Main registers: board registers and axis channels (§2, §3).
        Main = 0,
        /// Hub: the broadcast cache and the query registers (§6).
        Hub = 1,
        /// FPGA configuration PROM.
        FpgaProm = 2,
        /// QLA (companion board) PROM.
        QlaProm = 3,
        /// Ethernet controller.
        Ethernet = 4,
        /// FireWire packet buffer.
        FirewirePacket = 5,
        /// 1-wire memory.
        OneWire = 6,
        /// Data collection buffer.
        DataCollection = 7,
        /// Digital-output waveform table.
        Waveform = 8,
    }
}

open_enum! {
    /// A board register: main space, channel 0 (`fpga-board.md` §2, table
    /// "Board registers").
    pub enum BoardRegister(u8) {
        /// Offset 0: STATUS; reads the board state, writes mask/value pairs
        /// (§2 "STATUS read", "STATUS write").
        Status = 0,
        /// Offset 1: PHY_CTRL, requests a PHY register read or write (§2).
        PhyCtrl = 1,
        /// Offset 2: PHY_DATA, the result of a PHY register read (§2).
        PhyData = 2,
        /// Offset 3: WATCHDOG period in 5.208 us ticks (§2, §7).
        Watchdog = 3,
        /// Offset 4: HW_VERSION, the companion board's four-character code (§2).
        HwVersion = 4,
        /// Offset 5: TEMPERATURE, two 8-bit amplifier temperatures (§2).
        Temperature = 5,
        /// Offset 6: DIGITAL_OUT, written as mask and inverted bits (§2).
        DigitalOut = 6,
        /// Offset 7: FW_VERSION, the firmware revision (§2).
        FwVersion = 7,
        /// Offset 8: PROM_CMD, configuration PROM command (§2).
        PromCmd = 8,
        /// Offset 9: PROM_RESULT, configuration PROM result (§2).
        PromResult = 9,
        /// Offset 10: DIGITAL_IN, limits, home, encoder lines (§2).
        DigitalIn = 10,
        /// Offset 11: IP_ADDR, the IPv4 address, little-endian (§2).
        IpAddr = 11,
        /// Offset 12: ETH_STATUS, which tells the FPGA version (§2); on a V2
        /// also the KSZ8851 register access (extras §6).
        EthStatus = 12,
        /// Offset 13: DS_STATUS, the DS2505 1-wire interface (extras §4).
        DallasStatus = 13,
        /// Offset 14: the MAX7317 I/O expander (QLA 1.5+, extras §5).
        IoExpander = 14,
        /// Offset 15: GIT_DESC, the firmware's short commit id (§2).
        GitDesc = 15,
    }
}

open_enum! {
    /// An axis register: main space, channel 1..N (`fpga-board.md` §3,
    /// table "Axis registers"; seed 001 Table 1 for offsets 2, 3 and 7).
    pub enum AxisRegister(u8) {
        /// Offset 0: ADC, potentiometer and motor current (§3).
        Adc = 0,
        /// Offset 1: DAC, motor current command with valid bit (§3).
        Dac = 1,
        /// Offset 2: digital potentiometer control (seed 001 only, §3).
        DigpotCtrl = 2,
        /// Offset 3: digital potentiometer data (seed 001 only, §3).
        DigpotData = 3,
        /// Offset 4: ENC_PRELOAD, 24-bit encoder preload (§3).
        EncPreload = 4,
        /// Offset 5: ENC_POSITION, offset-binary encoder count (§3).
        EncPosition = 5,
        /// Offset 6: ENC_PERIOD, encoder period (Rev 7+, §3).
        EncPeriod = 6,
        /// Offset 7: ENC_QTR1, most recent quarter-cycle period (§3; the
        /// encoder frequency on seed 001).
        EncQtr1 = 7,
        /// Offset 8: DOUT_CTRL, the PWM / one-shot times of digital
        /// output N (extras §3).
        DoutCtrl = 8,
        /// Offset 9: ENC_QTR5, quarter-cycle period four edges back (§3).
        EncQtr5 = 9,
        /// Offset 10: ENC_RUN, clocks since the last encoder edge (§3).
        EncRun = 10,
        /// Offset 11: MOTOR_CONFIG, modes, enable delay, current limit (§3).
        MotorConfig = 11,
        /// Offset 12: MOTOR_STATUS, amplifier state and command (§3).
        MotorStatus = 12,
    }
}

/// Offset of the real-time block read and write (main space, address 0;
/// `fpga-board.md` §4, §5).
pub const REALTIME_BLOCK_OFFSET: u64 = 0;
/// Start of the hub memory, the broadcast cache (`fpga-board.md` §6.3).
pub const HUB_MEMORY_OFFSET: u64 = 0x1000;
/// Quadlets of hub memory (`fpga-board.md` §6.3).
pub const HUB_MEMORY_QUADLETS: usize = 512;
/// Hub register taking the broadcast query `{seq, mask}` (`fpga-board.md` §6.1).
pub const HUB_QUERY_OFFSET: u64 = 0x1800;
/// Hub register holding the number of quadlets written to hub memory
/// (`fpga-board.md` §6).
pub const HUB_QUADLETS_WRITTEN_OFFSET: u64 = 0x1802;
/// Destination offset of the status broadcasts (`fpga-board.md` §6.2); Rev 4-7
/// add [`STATUS_BROADCAST_BOARD_STRIDE`] times the board ID.
pub const STATUS_BROADCAST_OFFSET: u64 = 0xFFFF_FF00_1000;
/// Per-board step of the status broadcast offset on Rev 4-7 (`fpga-board.md` §6.2).
pub const STATUS_BROADCAST_BOARD_STRIDE: u64 = 0x20;
/// Priority field of the status broadcast block writes (`fpga-board.md` §6.2).
pub const STATUS_BROADCAST_PRIORITY: u8 = 0xA;
/// Physical ID that every board takes as broadcast (`fpga-board.md` §6.1).
pub const BROADCAST_NODE: u8 = 63;
/// Destination offset of the command block sent to node 63 (Ethernet;
/// `fpga-board.md` §6.5).
pub const COMMAND_BLOCK_OFFSET: u64 = 0;
/// Node the command block goes to when boards snoop it on FireWire
/// (`fpga-board.md` §6.5).
pub const COMMAND_SNOOP_NODE: u8 = 0;
/// Destination offset of the command block sent to node 0 (FireWire
/// snooping, `fpga-board.md` §6.5).
pub const COMMAND_SNOOP_OFFSET: u64 = 0xFFFF_FFFF_0000;

/// Where an offset lands on a board: its space and the 12-bit address
/// inside it (`fpga-board.md` §1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Address {
    /// The address space (bits 15:12).
    pub space: AddressSpace,
    /// The address inside the space (bits 11:0).
    pub index: u16,
}

impl Address {
    /// Decode a 48-bit offset; only its low 16 bits matter.
    pub fn from_offset(offset: u64) -> Address {
        let low = (offset & DECODED_BITS) as u32;
        Address {
            space: AddressSpace::from(field::SPACE.extract(low) as u8),
            index: field::INDEX.extract(low) as u16,
        }
    }

    /// The 16-bit offset addressing this location (high bits zero).
    ///
    /// # Errors
    /// [`Error::FieldRange`] if the space code exceeds 4 bits or the index
    /// 12 bits.
    pub fn offset(self) -> Result<u64> {
        let space = u8::from(self.space);
        check_max(
            "address space",
            u64::from(space),
            u64::from(field::SPACE.max()),
        )?;
        check_max(
            "address index",
            u64::from(self.index),
            u64::from(field::INDEX.max()),
        )?;
        let low = field::INDEX.insert(
            field::SPACE.insert(0, u32::from(space)),
            u32::from(self.index),
        );
        Ok(u64::from(low))
    }

    /// The main-space register at this address, if it is one.
    pub fn register(self) -> Option<Register> {
        if self.space != AddressSpace::Main {
            return None;
        }
        let index = u32::from(self.index);
        if field::MAIN_HIGH.extract(index) != 0 {
            return None;
        }
        let channel = field::CHANNEL.extract(index) as u8;
        let code = field::REGISTER.extract(index) as u8;
        Some(if channel == 0 {
            Register::Board(BoardRegister::from(code))
        } else {
            Register::Axis {
                axis: channel,
                register: AxisRegister::from(code),
            }
        })
    }

    /// The hub-space location at this address, if it is in the hub space.
    pub fn hub(self) -> Option<HubAddress> {
        (self.space == AddressSpace::Hub).then(|| HubAddress::from_index(self.index))
    }
}

/// A main-space register: channel 0 board register or an axis register
/// (`fpga-board.md` §1: address `0x00CO`, C = channel, O = offset).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Register {
    /// Channel 0 (§2).
    Board(BoardRegister),
    /// Channel `axis` (1-based, §3).
    Axis {
        /// The axis channel, 1..=15.
        axis: u8,
        /// The register in the channel.
        register: AxisRegister,
    },
}

impl Register {
    /// A board register.
    pub const fn board(register: BoardRegister) -> Register {
        Register::Board(register)
    }

    /// A register of axis `axis` (1-based).
    pub const fn axis(axis: u8, register: AxisRegister) -> Register {
        Register::Axis { axis, register }
    }

    /// Decode a 48-bit offset; `None` if it is not a main-space register
    /// address.
    pub fn from_offset(offset: u64) -> Option<Register> {
        Address::from_offset(offset).register()
    }

    /// The channel: 0 for board registers, the axis otherwise.
    pub fn channel(self) -> u8 {
        match self {
            Register::Board(_) => 0,
            Register::Axis { axis, .. } => axis,
        }
    }

    /// The register offset inside the channel.
    pub fn code(self) -> u8 {
        match self {
            Register::Board(r) => u8::from(r),
            Register::Axis { register, .. } => u8::from(register),
        }
    }

    /// The offset addressing this register.
    ///
    /// # Errors
    /// [`Error::InvalidValue`] for axis 0 (that is channel 0, the board);
    /// [`Error::FieldRange`] for an axis above 15 or a register code above 15.
    pub fn offset(self) -> Result<u64> {
        if let Register::Axis { axis: 0, .. } = self {
            return Err(Error::InvalidValue {
                what: "axis channel (axes are 1-based)",
                value: 0,
            });
        }
        let channel = self.channel();
        let code = self.code();
        check_max(
            "channel",
            u64::from(channel),
            u64::from(field::CHANNEL.max()),
        )?;
        check_max(
            "register offset",
            u64::from(code),
            u64::from(field::REGISTER.max()),
        )?;
        let low = field::REGISTER.insert(
            field::CHANNEL.insert(0, u32::from(channel)),
            u32::from(code),
        );
        Ok(u64::from(low))
    }
}

/// A location in the hub space (`fpga-board.md` §6.3, §6 "Hub registers").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HubAddress {
    /// Quadlet `n` (0..512) of the hub memory at `0x1000 + n`.
    Memory(u16),
    /// `0x1800`: the query register `{seq, mask}`.
    Query,
    /// `0x1802`: the number of quadlets written to hub memory.
    QuadletsWritten,
    /// Any other hub address (reads as 0); bits 11:0.
    Unmapped(u16),
}

impl HubAddress {
    const QUERY_INDEX: u16 = (HUB_QUERY_OFFSET - HUB_MEMORY_OFFSET) as u16;
    const WRITTEN_INDEX: u16 = (HUB_QUADLETS_WRITTEN_OFFSET - HUB_MEMORY_OFFSET) as u16;

    /// Decode bits 11:0 of a hub-space address.
    pub fn from_index(index: u16) -> HubAddress {
        match index {
            i if usize::from(i) < HUB_MEMORY_QUADLETS => HubAddress::Memory(i),
            Self::QUERY_INDEX => HubAddress::Query,
            Self::WRITTEN_INDEX => HubAddress::QuadletsWritten,
            other => HubAddress::Unmapped(other),
        }
    }

    /// The offset addressing this location.
    ///
    /// # Errors
    /// [`Error::FieldRange`] for a memory quadlet beyond 511 or an
    /// unmapped index beyond 12 bits.
    pub fn offset(self) -> Result<u64> {
        let index = match self {
            HubAddress::Memory(q) => {
                check_max(
                    "hub memory quadlet",
                    u64::from(q),
                    HUB_MEMORY_QUADLETS as u64 - 1,
                )?;
                q
            }
            HubAddress::Query => Self::QUERY_INDEX,
            HubAddress::QuadletsWritten => Self::WRITTEN_INDEX,
            HubAddress::Unmapped(i) => i,
        };
        Address {
            space: AddressSpace::Hub,
            index,
        }
        .offset()
    }
}

/// Check a board ID (0..=15).
pub(crate) fn check_board_id(board_id: u8) -> Result<()> {
    check_max("board id", u64::from(board_id), u64::from(MAX_BOARD_ID))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spaces_decode_from_bits_15_12() {
        for (offset, space) in [
            (0x0000u64, AddressSpace::Main),
            (0x1000, AddressSpace::Hub),
            (0x2000, AddressSpace::FpgaProm),
            (0x3000, AddressSpace::QlaProm),
            (0x4000, AddressSpace::Ethernet),
            (0x5000, AddressSpace::FirewirePacket),
            (0x6000, AddressSpace::OneWire),
            (0x7000, AddressSpace::DataCollection),
            (0x8000, AddressSpace::Waveform),
            (0xF123, AddressSpace::Unknown(15)),
        ] {
            let a = Address::from_offset(offset | 0xFFFF_0000_0000);
            assert_eq!(a.space, space);
            assert_eq!(a.offset().unwrap(), offset);
        }
    }

    #[test]
    fn register_map_examples() {
        assert_eq!(
            Register::from_offset(0),
            Some(Register::Board(BoardRegister::Status))
        );
        assert_eq!(
            Register::from_offset(0x0F),
            Some(Register::Board(BoardRegister::GitDesc))
        );
        assert_eq!(
            Register::from_offset(0x0D),
            Some(Register::Board(BoardRegister::DallasStatus))
        );
        assert_eq!(
            Register::from_offset(0x41),
            Some(Register::axis(4, AxisRegister::Dac))
        );
        assert_eq!(
            Register::from_offset(0x8C),
            Some(Register::axis(8, AxisRegister::MotorStatus))
        );
        // Bits 11:8 set: not a register.
        assert_eq!(Register::from_offset(0x0100), None);
        assert_eq!(Register::from_offset(0x1000), None);
        assert_eq!(Register::board(BoardRegister::IpAddr).offset(), Ok(0x0B));
        assert_eq!(Register::axis(1, AxisRegister::EncRun).offset(), Ok(0x1A));
        assert!(Register::axis(0, AxisRegister::Adc).offset().is_err());
        assert!(Register::axis(16, AxisRegister::Adc).offset().is_err());
        assert!(
            Register::axis(1, AxisRegister::Unknown(16))
                .offset()
                .is_err()
        );
    }

    #[test]
    fn every_main_offset_round_trips() {
        for offset in 0u64..0x100 {
            let reg = Register::from_offset(offset).unwrap();
            assert_eq!(reg.offset(), Ok(offset));
        }
    }

    #[test]
    fn hub_addresses() {
        let hub = |o: u64| Address::from_offset(o).hub();
        assert_eq!(hub(0x1000), Some(HubAddress::Memory(0)));
        assert_eq!(hub(0x11FF), Some(HubAddress::Memory(511)));
        assert_eq!(hub(0x1200), Some(HubAddress::Unmapped(0x200)));
        assert_eq!(hub(0x1800), Some(HubAddress::Query));
        assert_eq!(hub(0x1801), Some(HubAddress::Unmapped(0x801)));
        assert_eq!(hub(0x1802), Some(HubAddress::QuadletsWritten));
        assert_eq!(hub(0x0000), None);
        assert_eq!(hub(STATUS_BROADCAST_OFFSET), Some(HubAddress::Memory(0)));
        for h in [
            HubAddress::Memory(7),
            HubAddress::Query,
            HubAddress::QuadletsWritten,
            HubAddress::Unmapped(0x900),
        ] {
            assert_eq!(Address::from_offset(h.offset().unwrap()).hub(), Some(h));
        }
        assert!(HubAddress::Memory(512).offset().is_err());
        assert!(HubAddress::Unmapped(0x1000).offset().is_err());
        assert_eq!(
            Address::from_offset(COMMAND_SNOOP_OFFSET).register(),
            Some(Register::Board(BoardRegister::Status))
        );
    }

    #[test]
    fn board_ids() {
        assert!(check_board_id(15).is_ok());
        assert!(check_board_id(16).is_err());
    }
}
