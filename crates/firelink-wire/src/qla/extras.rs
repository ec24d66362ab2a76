//! Codecs for the firmware features beyond the servo path
//! (`fpga-board-extras.md`): the FPGA configuration PROM (M25P16) behind
//! PROM_CMD / PROM_RESULT and space 2, the QLA PROM (25AA128, space 3),
//! the DS2505 1-wire interface (register 13, space 6), the MAX7317 I/O
//! expander (register 14), the Ethernet status register of an FPGA V2
//! (register 12) and its KSZ8851 registers, and the serial-number formats
//! the reference host reads from the two PROMs. The digital outputs
//! (register 6, DOUT_CTRL, the waveform table) are in
//! [`registers`](crate::qla::registers).
//!
//! Raw bits only, each field defined once; what the board *does* with them
//! lives in the emulated firmware.
//!
//! ```
//! use firelink_wire::qla::extras::{PromCommand, PromOpcode, fpga_serial_image, parse_fpga_serial};
//! // GetFPGASerialNumber reads 16 bytes at 0x1FFF00 (extras §1).
//! let read = PromCommand::new(PromOpcode::Read, 0x1F_FF00);
//! assert_eq!(read.raw(), 0x031F_FF00);
//! let image = fpga_serial_image("1234-56").unwrap();
//! assert_eq!(&image[..12], b"FPGA 1234-56");
//! assert_eq!(parse_fpga_serial(&image), Ok("1234-56"));
//! ```

use crate::error::{Error, Result};
use crate::open_enum::open_enum;
use crate::qla::quadlet_register;

/// Bit fields of the extras' register quadlets, each defined once.
mod field {
    use crate::field::Field;

    // PROM_CMD write / read (extras §1).
    pub const PROM_OPCODE: Field = Field::new(0, 31, 24);
    pub const PROM_ADDRESS: Field = Field::new(0, 23, 0);
    pub const PROM_ERROR_INFO: Field = Field::new(0, 31, 16);
    pub const PROM_RELEASED: Field = Field::new(0, 8, 8);
    pub const PROM_CS: Field = Field::new(0, 7, 7);
    pub const PROM_SCLK: Field = Field::new(0, 6, 6);
    pub const PROM_MISO: Field = Field::new(0, 5, 5);
    pub const PROM_MOSI: Field = Field::new(0, 4, 4);
    pub const PROM_BLOCK_WRITE: Field = Field::new(0, 3, 3);
    pub const PROM_STATE: Field = Field::new(0, 2, 0);

    // QLA PROM command (extras §2).
    pub const QLA_OPCODE: Field = Field::new(0, 31, 24);
    pub const QLA_ADDRESS: Field = Field::new(0, 23, 8);
    pub const QLA_DATA: Field = Field::new(0, 7, 0);

    // DS2505 status / control, register 13 (extras §4).
    pub const DS_FAMILY: Field = Field::new(0, 31, 24);
    pub const DS_RISE: Field = Field::new(0, 23, 16);
    pub const DS_DS2480B: Field = Field::new(0, 15, 15);
    pub const DS_BUSY: Field = Field::new(0, 13, 13);
    pub const DS_STATE: Field = Field::new(0, 8, 4);
    pub const DS_BIDIRECTIONAL: Field = Field::new(0, 3, 3);
    pub const DS_RESET_RESULT: Field = Field::new(0, 2, 1);
    pub const DS_ENABLED: Field = Field::new(0, 0, 0);
    pub const DS_CTRL_ADDRESS: Field = Field::new(0, 26, 16);
    pub const DS_CTRL_END_SESSION: Field = Field::new(0, 3, 3);
    pub const DS_CTRL_MODE: Field = Field::new(0, 1, 0);

    // MAX7317 I/O expander, register 14 (extras §5).
    pub const EXP_CLEAR: Field = Field::new(0, 31, 31);
    pub const EXP_DEBUG: Field = Field::new(0, 30, 30);
    pub const EXP_UPPER: Field = Field::new(0, 31, 20);
    pub const EXP_ID: Field = Field::new(0, 19, 16);
    pub const EXP_COMMAND: Field = Field::new(0, 15, 0);
    pub const EXP_MARKER: Field = Field::new(0, 31, 29);
    pub const EXP_PROM_BUSY: Field = Field::new(0, 28, 28);
    pub const EXP_READ_WAITING: Field = Field::new(0, 27, 27);
    pub const EXP_PENDING: Field = Field::new(0, 26, 26);
    pub const EXP_POLL_ERROR: Field = Field::new(0, 25, 25);
    pub const EXP_MISMATCH: Field = Field::new(0, 24, 24);
    pub const EXP_MISMATCH_MASK: Field = Field::new(0, 23, 16);
    pub const EXP_ANSWER: Field = Field::new(0, 15, 0);
    pub const EXP_DBG_MISMATCH_MASK: Field = Field::new(0, 31, 24);
    pub const EXP_DBG_MISMATCH_COUNT: Field = Field::new(0, 23, 16);
    pub const EXP_DBG_READ: Field = Field::new(0, 15, 8);
    pub const EXP_DBG_COMMANDED: Field = Field::new(0, 7, 0);

    // ETH_STATUS of an FPGA V2, register 12 (extras §6).
    pub const ETH_PRESENT: Field = Field::new(0, 31, 31);
    pub const ETH_KSZ_REQUEST_ERROR: Field = Field::new(0, 30, 30);
    pub const ETH_KSZ_INIT_OK: Field = Field::new(0, 29, 29);
    pub const ETH_FRAME_ERROR: Field = Field::new(0, 28, 28);
    pub const ETH_IPV4_ERROR: Field = Field::new(0, 27, 27);
    pub const ETH_UDP_PORT_ERROR: Field = Field::new(0, 26, 26);
    pub const ETH_DESTINATION_ERROR: Field = Field::new(0, 25, 25);
    pub const ETH_BUS_ACCESS_ERROR: Field = Field::new(0, 24, 24);
    pub const ETH_KSZ_STATE_ERROR: Field = Field::new(0, 23, 23);
    pub const ETH_SEND_STATE_ERROR: Field = Field::new(0, 22, 22);
    pub const ETH_UDP_MODE: Field = Field::new(0, 20, 20);
    pub const ETH_LINK_UP: Field = Field::new(0, 19, 19);
    pub const ETH_KSZ_IDLE: Field = Field::new(0, 18, 18);
    pub const ETH_WAIT_POINT: Field = Field::new(0, 17, 16);
    pub const ETH_DATA: Field = Field::new(0, 15, 0);
    pub const ETH_CLEAR_ETH_ERRORS: Field = Field::new(0, 29, 29);
    pub const ETH_CLEAR_KSZ_ERRORS: Field = Field::new(0, 28, 28);
    pub const ETH_DMA: Field = Field::new(0, 27, 27);
    pub const ETH_RESET_KSZ: Field = Field::new(0, 26, 26);
    pub const ETH_WRITE: Field = Field::new(0, 25, 25);
    pub const ETH_WORD: Field = Field::new(0, 24, 24);
    pub const ETH_REGISTER: Field = Field::new(0, 23, 16);
    pub const ETH_NOT_ACCESS: Field = Field::new(0, 31, 28);
}

// ------------------------------------------------------------ addresses ---

/// Space 2: the FPGA PROM's 256-byte read buffer / page-program stream,
/// 64 quadlets (extras §1).
pub const FPGA_PROM_BUFFER_OFFSET: u64 = 0x2000;
/// Quadlets of the FPGA PROM buffer.
pub const FPGA_PROM_BUFFER_QUADLETS: usize = 64;
/// QLA PROM command register of channel 0 (extras §2); channel `c` (DQLA:
/// 1 and 2) adds `c << 4`.
pub const QLA_PROM_COMMAND_OFFSET: u64 = 0x3000;
/// QLA PROM status register of channel 0 (bits 2:0 state, 0 = idle).
pub const QLA_PROM_STATUS_OFFSET: u64 = 0x3001;
/// QLA PROM result register of channel 0.
pub const QLA_PROM_RESULT_OFFSET: u64 = 0x3002;
/// QLA PROM data buffer of channel 0, 16 quadlets.
pub const QLA_PROM_BUFFER_OFFSET: u64 = 0x3100;
/// Quadlets of the QLA PROM data buffer.
pub const QLA_PROM_BUFFER_QUADLETS: usize = 16;
/// Space 4: the Ethernet debug window (extras §6).
pub const ETH_WINDOW_OFFSET: u64 = 0x4000;
/// Space 6: the 256 bytes the DS2505 interface read last (extras §4).
pub const DALLAS_BUFFER_OFFSET: u64 = 0x6000;
/// Quadlets of the DS2505 buffer.
pub const DALLAS_BUFFER_QUADLETS: usize = 64;
/// Space 8: the digital-output waveform table (extras §3).
pub const WAVEFORM_TABLE_OFFSET: u64 = 0x8000;

// ------------------------------------------------------------ FPGA PROM ---

/// Size of the M25P16 configuration PROM: 2 MiB.
pub const FPGA_PROM_BYTES: usize = 0x20_0000;
/// Its erase sector: 64 KiB.
pub const FPGA_PROM_SECTOR_BYTES: usize = 0x1_0000;
/// Its program page: 256 bytes.
pub const FPGA_PROM_PAGE_BYTES: usize = 256;
/// The JEDEC ID the read-ID command returns (`0x20 0x20 0x15`).
pub const FPGA_PROM_ID: u32 = 0x0020_2015;
/// The old-style electronic signature the wake command returns.
pub const FPGA_PROM_SIGNATURE: u32 = 0x14;
/// Where the FPGA serial number is kept (a page of the last sector).
pub const FPGA_SERIAL_ADDRESS: u32 = 0x1F_FF00;
/// Bytes of the serial-number image the host reads.
pub const SERIAL_IMAGE_BYTES: usize = 16;
/// The status byte's write-in-progress bit (M25P16 and 25AA128).
pub const PROM_STATUS_WIP: u8 = 0x01;
/// The status byte's write-enable-latch bit (M25P16 and 25AA128).
pub const PROM_STATUS_WEL: u8 = 0x02;

open_enum! {
    /// M25P16 opcodes the firmware accepts at PROM_CMD (extras §1 table).
    pub enum PromOpcode(u8) {
        /// Write status register.
        WriteStatus = 0x01,
        /// Page program (carried by a block write to space 2, not PROM_CMD).
        PageProgram = 0x02,
        /// Read 256 bytes into the buffer.
        Read = 0x03,
        /// Write disable.
        WriteDisable = 0x04,
        /// Read the status byte.
        ReadStatus = 0x05,
        /// Write enable.
        WriteEnable = 0x06,
        /// Fast read, as `Read`.
        FastRead = 0x0B,
        /// Wake from deep power-down (returns the old ID `0x14`).
        Wake = 0xAB,
        /// Deep power-down.
        DeepPowerDown = 0xB9,
        /// Bulk erase.
        BulkErase = 0xC7,
        /// Erase the 64 KiB sector containing the address.
        SectorErase = 0xD8,
        /// Read the JEDEC ID.
        ReadId = 0x9F,
        /// Bit-bang the SPI pins (debug).
        BitBang = 0xFF,
    }
}

quadlet_register! {
    /// PROM_CMD as written (register 8): opcode and 24-bit PROM address;
    /// also quadlet 0 of a page-program block write.
    pub struct PromCommand {
        /// M25P16 opcode, bits 31:24 (see [`PromOpcode`]).
        opcode_bits, set_opcode_bits, with_opcode_bits: u8 = field::PROM_OPCODE;
        /// PROM byte address, bits 23:0.
        address, set_address, with_address: u32 = field::PROM_ADDRESS;
    }
}

impl PromCommand {
    /// A command word.
    pub fn new(opcode: PromOpcode, address: u32) -> PromCommand {
        PromCommand::default()
            .with_opcode_bits(opcode.into())
            .with_address(address)
    }

    /// The opcode.
    pub fn opcode(self) -> PromOpcode {
        PromOpcode::from(self.opcode_bits())
    }
}

quadlet_register! {
    /// PROM_CMD as read (register 8; bits 15:0 also QLA PROM status).
    pub struct PromStatus {
        /// Non-zero after a page-program stream with an out-of-order
        /// quadlet: `{00, addr[5:0], 0, expected[6:0]}`, bits 31:16.
        error_info, set_error_info, with_error_info: u16 = field::PROM_ERROR_INFO;
        /// SPI pins released, bit 8.
        released, set_released, with_released: bool = field::PROM_RELEASED;
        /// Chip select, bit 7.
        cs, set_cs, with_cs: bool = field::PROM_CS;
        /// SPI clock, bit 6.
        sclk, set_sclk, with_sclk: bool = field::PROM_SCLK;
        /// MISO, bit 5.
        miso, set_miso, with_miso: bool = field::PROM_MISO;
        /// MOSI, bit 4.
        mosi, set_mosi, with_mosi: bool = field::PROM_MOSI;
        /// A page-program block write is in progress, bit 3.
        block_write, set_block_write, with_block_write: bool = field::PROM_BLOCK_WRITE;
        /// Interface state, bits 2:0 (0 = idle: the result is ready).
        state, set_state, with_state: u8 = field::PROM_STATE;
    }
}

// ------------------------------------------------------------- QLA PROM ---

/// Size of the 25AA128 QLA PROM: 16 KiB (14-bit byte address).
pub const QLA_PROM_BYTES: usize = 0x4000;
/// Its write page: 64 bytes.
pub const QLA_PROM_PAGE_BYTES: usize = 64;
/// Bytes of the QLA serial number the host reads (3 quadlets at 0).
pub const QLA_SERIAL_READ_BYTES: usize = 12;

open_enum! {
    /// QLA PROM commands at `0x3000` (extras §2).
    pub enum QlaPromOpcode(u8) {
        /// Write the status byte.
        WriteStatus = 0x01,
        /// Write one byte.
        WriteByte = 0x02,
        /// Read one byte (result bits 7:0).
        ReadByte = 0x03,
        /// Write disable.
        WriteDisable = 0x04,
        /// Read the status byte (result bits 7:0).
        ReadStatus = 0x05,
        /// Write enable.
        WriteEnable = 0x06,
        /// Read `n` = data + 1 quadlets (1..=16) into the buffer.
        ReadBlock = 0xFE,
        /// Write buffer quadlets `0..n` (n = data + 1) as one page write.
        WriteBlock = 0xFF,
    }
}

quadlet_register! {
    /// A QLA PROM command (`0x3000`): opcode, 16-bit address (the top two
    /// bits ignored by the chip), data byte or quadlet count - 1.
    pub struct QlaPromCommand {
        /// Opcode, bits 31:24 (see [`QlaPromOpcode`]).
        opcode_bits, set_opcode_bits, with_opcode_bits: u8 = field::QLA_OPCODE;
        /// PROM byte address, bits 23:8.
        address, set_address, with_address: u16 = field::QLA_ADDRESS;
        /// Data byte (byte write, status write) or quadlets - 1 (blocks), bits 7:0.
        data, set_data, with_data: u8 = field::QLA_DATA;
    }
}

impl QlaPromCommand {
    /// A command word.
    pub fn new(opcode: QlaPromOpcode, address: u16, data: u8) -> QlaPromCommand {
        QlaPromCommand::default()
            .with_opcode_bits(opcode.into())
            .with_address(address)
            .with_data(data)
    }

    /// The opcode.
    pub fn opcode(self) -> QlaPromOpcode {
        QlaPromOpcode::from(self.opcode_bits())
    }
}

// -------------------------------------------------------- serial numbers ---

fn check_serial(serial: &str, max: usize, what: &'static str) -> Result<()> {
    let printable = serial.bytes().all(|b| (0x21..=0x7E).contains(&b));
    if serial.is_empty() || serial.len() > max || !printable {
        return Err(Error::InvalidValue {
            what,
            value: serial.len() as u32,
        });
    }
    Ok(())
}

/// The longest FPGA serial number (16 bytes less `"FPGA "`).
pub const FPGA_SERIAL_MAX: usize = SERIAL_IMAGE_BYTES - 5;
/// The longest QLA serial number (12 bytes less `"QLA "`).
pub const QLA_SERIAL_MAX: usize = QLA_SERIAL_READ_BYTES - 4;

/// The 16 bytes `pgm1394` programs at [`FPGA_SERIAL_ADDRESS`]: `"FPGA "`,
/// the serial, `0xFF` to the end (extras §1; `FPGA 1234-56` is
/// `46504741 20313233 342D3536 FFFFFFFF`).
///
/// # Errors
/// [`Error::InvalidValue`] (value = its length) for a serial that is
/// empty, longer than [`FPGA_SERIAL_MAX`] or not printable ASCII without
/// spaces.
pub fn fpga_serial_image(serial: &str) -> Result<[u8; SERIAL_IMAGE_BYTES]> {
    check_serial(serial, FPGA_SERIAL_MAX, "FPGA serial number length")?;
    let mut image = [0xFF; SERIAL_IMAGE_BYTES];
    let text = b"FPGA ".iter().chain(serial.as_bytes());
    for (dst, b) in image.iter_mut().zip(text) {
        *dst = *b;
    }
    Ok(image)
}

/// The FPGA serial number in the bytes read at [`FPGA_SERIAL_ADDRESS`], as
/// the reference host reads it: prefix `"FPGA "`, cut at the first `0xFF`.
///
/// # Errors
/// [`Error::InvalidValue`] (value = the first four bytes) without the
/// prefix or with text that is not ASCII.
pub fn parse_fpga_serial(bytes: &[u8]) -> Result<&str> {
    let bytes = bytes.get(..SERIAL_IMAGE_BYTES).unwrap_or(bytes);
    let end = bytes.iter().position(|b| *b == 0xFF).unwrap_or(bytes.len());
    let text = bytes.get(..end).unwrap_or(&[]);
    let bad = Error::InvalidValue {
        what: "FPGA serial number (no \"FPGA \" prefix)",
        value: first_quadlet(bytes),
    };
    let rest = text.strip_prefix(b"FPGA ").ok_or(bad)?;
    core::str::from_utf8(rest)
        .ok()
        .filter(|s| s.is_ascii())
        .ok_or(bad)
}

/// The bytes the QLA serial number occupies from PROM address 0: `"QLA "`,
/// the serial, a terminating 0 and `0xFF` to the end (the tools write the
/// 0; erased bytes read `0xFF`). `QLA 1234-56` reads `514C4120 31323334
/// 2D353600` (extras §2).
///
/// # Errors
/// [`Error::InvalidValue`] (value = its length) for a serial that is
/// empty, longer than [`QLA_SERIAL_MAX`] or not printable ASCII without
/// spaces.
pub fn qla_serial_image(serial: &str) -> Result<[u8; SERIAL_IMAGE_BYTES]> {
    check_serial(serial, QLA_SERIAL_MAX, "QLA serial number length")?;
    let mut image = [0xFF; SERIAL_IMAGE_BYTES];
    let text = b"QLA ".iter().chain(serial.as_bytes()).chain(&[0u8]);
    for (dst, b) in image.iter_mut().zip(text) {
        *dst = *b;
    }
    Ok(image)
}

/// The QLA serial number in the first [`QLA_SERIAL_READ_BYTES`] bytes of
/// the QLA PROM, as the reference host reads it: trailing `0xFF` and 0
/// stripped, prefix `"QLA "` (or `"dRA "`) required.
///
/// # Errors
/// [`Error::InvalidValue`] (value = the first four bytes) without a known
/// prefix or with text that is not ASCII.
pub fn parse_qla_serial(bytes: &[u8]) -> Result<&str> {
    let bytes = bytes.get(..QLA_SERIAL_READ_BYTES).unwrap_or(bytes);
    let end = bytes
        .iter()
        .rposition(|b| *b != 0xFF && *b != 0)
        .map_or(0, |i| i + 1);
    let text = bytes.get(..end).unwrap_or(&[]);
    let bad = Error::InvalidValue {
        what: "QLA serial number (no \"QLA \" prefix)",
        value: first_quadlet(bytes),
    };
    let rest = text
        .strip_prefix(b"QLA ")
        .or_else(|| text.strip_prefix(b"dRA "))
        .ok_or(bad)?;
    core::str::from_utf8(rest)
        .ok()
        .filter(|s| s.is_ascii())
        .ok_or(bad)
}

fn first_quadlet(bytes: &[u8]) -> u32 {
    let mut q = [0u8; 4];
    for (dst, b) in q.iter_mut().zip(bytes) {
        *dst = *b;
    }
    u32::from_be_bytes(q)
}

// ---------------------------------------------------------------- DS2505 ---

/// Family code of the DS2505 in an instrument.
pub const DS2505_FAMILY: u8 = 0x0B;
/// Bytes of DS2505 memory.
pub const DS2505_BYTES: usize = 2048;

open_enum! {
    /// The 1-wire reset result, DSSTAT bits 2:1 (extras §4).
    pub enum DallasReset(u8) {
        /// No reset tried yet.
        NotTried = 0,
        /// A device answered.
        Answered = 1,
        /// The line did not rise: missing pull-up.
        NoRise = 2,
        /// No presence pulse: no instrument.
        NoPresence = 3,
    }
}

quadlet_register! {
    /// Register 13 as read (DSSTAT, extras §4).
    pub struct DallasStatus {
        /// Family code of the last device read (DS2505 = `0x0B`), bits 31:24.
        family, set_family, with_family: u8 = field::DS_FAMILY;
        /// Measured rise time in clocks (direct 1-wire) or the last byte
        /// from a DS2480B, bits 23:16.
        rise_time, set_rise_time, with_rise_time: u8 = field::DS_RISE;
        /// A DS2480B serial driver is in use, bit 15.
        ds2480b, set_ds2480b, with_ds2480b: bool = field::DS_DS2480B;
        /// Busy, bit 13.
        busy, set_busy, with_busy: bool = field::DS_BUSY;
        /// Interface state, bits 8:4 (0 = idle).
        state, set_state, with_state: u8 = field::DS_STATE;
        /// Bidirectional digital outputs (QLA 1.4+), bit 3.
        bidirectional, set_bidirectional, with_bidirectional: bool = field::DS_BIDIRECTIONAL;
        /// Reset result, bits 2:1 (see [`DallasReset`]).
        reset_bits, set_reset_bits, with_reset_bits: u8 = field::DS_RESET_RESULT;
        /// The interface is enabled (owns DOUT3), bit 0.
        enabled, set_enabled, with_enabled: bool = field::DS_ENABLED;
    }
}

impl DallasStatus {
    /// The reset result.
    pub fn reset(self) -> DallasReset {
        DallasReset::from(self.reset_bits())
    }
}

open_enum! {
    /// What a register-13 write asks, bits 1:0 (extras §4).
    pub enum DallasMode(u8) {
        /// Release DOUT3.
        Release = 0,
        /// Take DOUT3.
        Take = 1,
        /// Enable, reset, read 256 bytes from the address.
        ReadFirst = 2,
        /// Read the next 256 bytes.
        ReadNext = 3,
    }
}

quadlet_register! {
    /// Register 13 as written (extras §4).
    pub struct DallasControl {
        /// 11-bit start address of a first read, bits 26:16.
        address, set_address, with_address: u16 = field::DS_CTRL_ADDRESS;
        /// End a DS2480B session (flush, reset), bit 3.
        end_session, set_end_session, with_end_session: bool = field::DS_CTRL_END_SESSION;
        /// What to do, bits 1:0 (see [`DallasMode`]).
        mode_bits, set_mode_bits, with_mode_bits: u8 = field::DS_CTRL_MODE;
    }
}

impl DallasControl {
    /// What the write asks.
    pub fn mode(self) -> DallasMode {
        DallasMode::from(self.mode_bits())
    }
}

// -------------------------------------------------------- I/O expander ---

/// The marker bits 31:29 of a normal I/O-expander read (`010`).
pub const EXPANDER_READ_MARKER: u8 = 0b010;

quadlet_register! {
    /// Register 14 as written (extras §5). The SPI command in bits 15:0 is
    /// sent only when bits 31:20 are 0.
    pub struct ExpanderWrite {
        /// Clear the error flags and counter, bit 31.
        clear, set_clear, with_clear: bool = field::EXP_CLEAR;
        /// Select the debug read-out, bit 30.
        debug, set_debug, with_debug: bool = field::EXP_DEBUG;
        /// Expander ID (0 on a QLA1), bits 19:16.
        id, set_id, with_id: u8 = field::EXP_ID;
        /// MAX7317 command: bit 15 read, 14:8 register, 7:0 data.
        command, set_command, with_command: u16 = field::EXP_COMMAND;
    }
}

impl ExpanderWrite {
    /// Whether the write sends its SPI command (bits 31:20 zero).
    pub fn sends_command(self) -> bool {
        field::EXP_UPPER.extract(self.0) == 0
    }
}

quadlet_register! {
    /// Register 14 as read, normal read-out (extras §5).
    pub struct ExpanderRead {
        /// Always `010`, bits 31:29.
        marker, set_marker, with_marker: u8 = field::EXP_MARKER;
        /// The SPI bus is busy with the QLA PROM, bit 28.
        prom_busy, set_prom_busy, with_prom_busy: bool = field::EXP_PROM_BUSY;
        /// A host read awaits its answer, bit 27.
        read_waiting, set_read_waiting, with_read_waiting: bool = field::EXP_READ_WAITING;
        /// A host command is pending, bit 26.
        pending, set_pending, with_pending: bool = field::EXP_PENDING;
        /// A poll read failed, bit 25.
        poll_error, set_poll_error, with_poll_error: bool = field::EXP_POLL_ERROR;
        /// An output does not read back as commanded, bit 24.
        mismatch, set_mismatch, with_mismatch: bool = field::EXP_MISMATCH;
        /// Which ports 7:0 mismatch, bits 23:16.
        mismatch_mask, set_mismatch_mask, with_mismatch_mask: u8 = field::EXP_MISMATCH_MASK;
        /// Answer to the host's last read: 15:8 its command's upper byte
        /// (`0x80 | register`), 7:0 the data.
        answer, set_answer, with_answer: u16 = field::EXP_ANSWER;
    }
}

quadlet_register! {
    /// Register 14 as read, debug read-out (extras §5).
    pub struct ExpanderDebug {
        /// Mismatch mask, bits 31:24.
        mismatch_mask, set_mismatch_mask, with_mismatch_mask: u8 = field::EXP_DBG_MISMATCH_MASK;
        /// Mismatch count, bits 23:16.
        mismatch_count, set_mismatch_count, with_mismatch_count: u8 =
            field::EXP_DBG_MISMATCH_COUNT;
        /// Ports 7:0 as read back, bits 15:8.
        ports_read, set_ports_read, with_ports_read: u8 = field::EXP_DBG_READ;
        /// Ports 7:0 as commanded, bits 7:0.
        ports_commanded, set_ports_commanded, with_ports_commanded: u8 =
            field::EXP_DBG_COMMANDED;
    }
}

// ------------------------------------------------------------- Ethernet ---

/// What every quadlet of `0x4080-0x409F` reads on an FPGA V2 built
/// without debug data (Rev 8): `"DBG0"`.
pub const ETH_DEBUG_ABSENT: u32 = 0x3047_4244;

quadlet_register! {
    /// ETH_STATUS of an FPGA V2 as read (register 12, extras §6). A healthy
    /// UDP link reads `0xA01C0000 | data`.
    pub struct EthStatusV2 {
        /// Ethernet present (V2), bit 31.
        present, set_present, with_present: bool = field::ETH_PRESENT;
        /// KSZ register request error, bit 30.
        ksz_request_error, set_ksz_request_error, with_ksz_request_error: bool =
            field::ETH_KSZ_REQUEST_ERROR;
        /// KSZ8851 initialised OK, bit 29.
        ksz_init_ok, set_ksz_init_ok, with_ksz_init_ok: bool = field::ETH_KSZ_INIT_OK;
        /// Frame error, bit 28.
        frame_error, set_frame_error, with_frame_error: bool = field::ETH_FRAME_ERROR;
        /// IPv4 error, bit 27.
        ipv4_error, set_ipv4_error, with_ipv4_error: bool = field::ETH_IPV4_ERROR;
        /// UDP port error, bit 26.
        udp_port_error, set_udp_port_error, with_udp_port_error: bool = field::ETH_UDP_PORT_ERROR;
        /// Destination error, bit 25.
        destination_error, set_destination_error, with_destination_error: bool =
            field::ETH_DESTINATION_ERROR;
        /// Bus access error, bit 24.
        bus_access_error, set_bus_access_error, with_bus_access_error: bool =
            field::ETH_BUS_ACCESS_ERROR;
        /// KSZ state error, bit 23.
        ksz_state_error, set_ksz_state_error, with_ksz_state_error: bool =
            field::ETH_KSZ_STATE_ERROR;
        /// Send state error, bit 22.
        send_state_error, set_send_state_error, with_send_state_error: bool =
            field::ETH_SEND_STATE_ERROR;
        /// UDP mode (0 = raw Ethernet), bit 20.
        udp_mode, set_udp_mode, with_udp_mode: bool = field::ETH_UDP_MODE;
        /// Link up, bit 19.
        link_up, set_link_up, with_link_up: bool = field::ETH_LINK_UP;
        /// KSZ state machine idle, bit 18.
        ksz_idle, set_ksz_idle, with_ksz_idle: bool = field::ETH_KSZ_IDLE;
        /// Wait point (0 none), bits 17:16.
        wait_point, set_wait_point, with_wait_point: u8 = field::ETH_WAIT_POINT;
        /// The last KSZ register read, bits 15:0.
        data, set_data, with_data: u16 = field::ETH_DATA;
    }
}

quadlet_register! {
    /// Register 12 as written (extras §6): error clears, KSZ reset, or one
    /// KSZ8851 register access (done only when bits 31:28 and 26 are 0).
    pub struct EthControl {
        /// Clear the EthernetIO errors, bit 29.
        clear_eth_errors, set_clear_eth_errors, with_clear_eth_errors: bool =
            field::ETH_CLEAR_ETH_ERRORS;
        /// Clear the KSZ errors, bit 28.
        clear_ksz_errors, set_clear_ksz_errors, with_clear_ksz_errors: bool =
            field::ETH_CLEAR_KSZ_ERRORS;
        /// DMA access, bit 27.
        dma, set_dma, with_dma: bool = field::ETH_DMA;
        /// Reset the KSZ8851 (the host then waits 100 ms), bit 26.
        reset_ksz, set_reset_ksz, with_reset_ksz: bool = field::ETH_RESET_KSZ;
        /// Write (1) or read (0), bit 25.
        write, set_write, with_write: bool = field::ETH_WRITE;
        /// 16-bit word (1) or byte (0), bit 24.
        word, set_word, with_word: bool = field::ETH_WORD;
        /// KSZ8851 register, bits 23:16.
        register, set_register, with_register: u8 = field::ETH_REGISTER;
        /// Data to write, bits 15:0.
        data, set_data, with_data: u16 = field::ETH_DATA;
    }
}

impl EthControl {
    /// Whether the write is a KSZ register access (bits 31:28 and 26 zero).
    pub fn is_access(self) -> bool {
        field::ETH_NOT_ACCESS.extract(self.0) == 0 && !self.reset_ksz()
    }

    /// The host's 16-bit register read (`ReadKSZ8851Reg`).
    pub fn read_word(register: u8) -> EthControl {
        EthControl::default()
            .with_word(true)
            .with_register(register)
    }
}

/// KSZ8851 registers the reference host checks (extras §6).
pub mod ksz8851 {
    /// MAC address low word: `0x940n`, n = board ID.
    pub const MARL: u8 = 0x10;
    /// MAC address middle word: `0x0E13`.
    pub const MARM: u8 = 0x12;
    /// MAC address high word: `0xFA61` (MAC FA:61:0E:13:94:0n).
    pub const MARH: u8 = 0x14;
    /// Receive frame control 1: `& 0x1FF == 0x1EF`.
    pub const RXCR1: u8 = 0x70;
    /// Transmit control: `0x7CE1`... (fpgatest reads `0x74`).
    pub const RXCR2: u8 = 0x74;
    /// Receive queue command: `& 0x3F7 == 0x020`.
    pub const RXQCR: u8 = 0x82;
    /// TX frame data pointer: bit 14 set.
    pub const TXFDPR: u8 = 0x84;
    /// RX frame data pointer: bit 14 set.
    pub const RXFDPR: u8 = 0x86;
    /// Interrupt enable: `0xA000`.
    pub const IER: u8 = 0x90;
    /// RX frame count threshold: `& 0xFF == 1`.
    pub const RXFCTR: u8 = 0x9C;
    /// Multicast hash table register 1 (the one the host checks): `0x0008`.
    pub const MAHTR1: u8 = 0xA2;
    /// Chip ID and enable: `& 0xFFF0 == 0x8870`.
    pub const CIDER: u8 = 0xC0;
    /// Port 1 status: healthy link `0x0660` set, `0x2000` clear.
    pub const P1SR: u8 = 0xF8;
    /// P1SR: link good.
    pub const P1SR_LINK_GOOD: u16 = 0x0020;
    /// P1SR: auto-negotiation done.
    pub const P1SR_AUTONEG_DONE: u16 = 0x0040;
    /// P1SR: full duplex.
    pub const P1SR_FULL_DUPLEX: u16 = 0x0200;
    /// P1SR: 100 Mbit/s.
    pub const P1SR_100MBPS: u16 = 0x0400;
    /// P1SR: polarity reversed.
    pub const P1SR_POLARITY_REVERSED: u16 = 0x2000;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn serial_images_match_the_spec_vectors() {
        // extras §1: `FPGA 1234-56` = 46504741 20313233 342D3536 FFFFFFFF.
        let f = fpga_serial_image("1234-56").unwrap();
        let mut quads = f
            .chunks(4)
            .map(|c| u32::from_be_bytes(c.try_into().unwrap()));
        for q in [0x4650_4741, 0x2031_3233, 0x342D_3536, 0xFFFF_FFFF] {
            assert_eq!(quads.next(), Some(q));
        }
        assert_eq!(parse_fpga_serial(&f), Ok("1234-56"));
        assert_eq!(
            parse_fpga_serial(&fpga_serial_image("1234-567").unwrap()),
            Ok("1234-567")
        );
        // extras §2: `QLA 1234-56`+0 = 514C4120 31323334 2D353600.
        let q = qla_serial_image("1234-56").unwrap();
        assert_eq!(&q[..12], b"QLA 1234-56\0");
        assert_eq!(parse_qla_serial(&q), Ok("1234-56"));
        // An 8-character serial fills the 12 bytes the host reads.
        assert_eq!(
            parse_qla_serial(&qla_serial_image("1234-567").unwrap()),
            Ok("1234-567")
        );
        // dRA prefix; erased memory; no prefix.
        assert_eq!(
            parse_qla_serial(b"dRA 42\xFF\xFF\xFF\xFF\xFF\xFF"),
            Ok("42")
        );
        assert!(parse_qla_serial(&[0xFF; 12]).is_err());
        assert!(parse_fpga_serial(&[0xFF; 16]).is_err());
        // Too long, empty, spaces.
        assert!(fpga_serial_image("123456789012").is_err());
        assert!(qla_serial_image("123456789").is_err());
        assert!(qla_serial_image("").is_err());
        assert!(qla_serial_image("12 34").is_err());
    }

    #[test]
    fn command_words() {
        assert_eq!(PromCommand::new(PromOpcode::ReadId, 0).raw(), 0x9F00_0000);
        assert_eq!(PromCommand(0xD81F_0000).opcode(), PromOpcode::SectorErase);
        assert_eq!(PromCommand(0xD81F_0000).address(), 0x1F_0000);
        assert_eq!(
            QlaPromCommand::new(QlaPromOpcode::ReadBlock, 0, 2).raw(),
            0xFE00_0002
        );
        assert_eq!(QlaPromCommand(0x0200_1234).address(), 0x12);
        assert_eq!(QlaPromCommand(0x0200_1234).data(), 0x34);
        // DallasReadTool's first write: read 256 bytes from 0x80.
        let c = DallasControl(0x0080_0002);
        assert_eq!(c.mode(), DallasMode::ReadFirst);
        assert_eq!(c.address(), 0x80);
        // A healthy UDP link (extras §6).
        let e = EthStatusV2::default()
            .with_present(true)
            .with_ksz_init_ok(true)
            .with_udp_mode(true)
            .with_link_up(true)
            .with_ksz_idle(true);
        assert_eq!(e.raw(), 0xA01C_0000);
        assert!(EthControl::read_word(0xC0).is_access());
        assert!(!EthControl(0x0400_0000).is_access());
        assert!(ExpanderWrite(0x0000_1345).sends_command());
        assert!(!ExpanderWrite(0x4000_0000).sends_command());
        assert_eq!(DallasStatus(0x0030_000F).reset(), DallasReset::NoPresence);
    }
}
