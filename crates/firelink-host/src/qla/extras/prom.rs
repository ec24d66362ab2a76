//! The FPGA configuration PROM and the QLA PROM (`fpga-board-extras.md`
//! §1, §2), with the serial numbers they hold: the reference host's
//! `PromGetId`, `PromGetStatus`, `PromReadData`, `PromSectorErase`,
//! `PromProgramPage`, `GetFPGASerialNumber`, the 25AA128 byte and block
//! accesses and `GetQLASerialNumber`.

use std::time::Duration;

use firelink_wire::qla::address::BoardRegister;
use firelink_wire::qla::extras::{
    FPGA_PROM_BUFFER_OFFSET, FPGA_PROM_PAGE_BYTES, FPGA_SERIAL_ADDRESS, PROM_STATUS_WIP,
    PromCommand, PromOpcode, PromStatus, QLA_PROM_BUFFER_OFFSET, QLA_PROM_BUFFER_QUADLETS,
    QLA_PROM_COMMAND_OFFSET, QLA_PROM_RESULT_OFFSET, QLA_SERIAL_READ_BYTES, QlaPromCommand,
    QlaPromOpcode, SERIAL_IMAGE_BYTES, fpga_serial_image, parse_fpga_serial, parse_qla_serial,
    qla_serial_image,
};

use super::{FeatureError, Result, board_register, prom_delay};
use crate::port::{Dest, Port};

/// Bytes the host reads per PROM read command (of the 256 the board
/// fills).
const READ_CHUNK: usize = 64;
/// Polls of PROM_CMD the host makes for a command to finish, 10 us apart.
const POLLS: usize = 8;
/// Longest wait for a write cycle (erase, program) to end: more than the
/// M25P16's 3 s maximum sector erase.
const WRITE_CYCLE_LIMIT: Duration = Duration::from_secs(5);
/// Pause between status polls during a write cycle.
const WRITE_CYCLE_POLL: Duration = Duration::from_millis(1);

fn cmd_register() -> u64 {
    board_register(BoardRegister::PromCmd)
}

fn result_register() -> u64 {
    board_register(BoardRegister::PromResult)
}

/// Write a PROM command, wait for the interface to be idle, and read the
/// result.
fn fpga_command<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
    cmd: PromCommand,
    what: &'static str,
) -> Result<u32> {
    port.write_quadlet(dest, cmd_register(), cmd.raw())?;
    port.wait(prom_delay(port));
    wait_idle(port, dest, what, 0x7)?;
    Ok(port.read_quadlet(dest, result_register())?)
}

/// Set the FPGA PROM's write-enable latch (every erase or program needs it
/// first).
fn fpga_write_enable<P: Port + ?Sized>(port: &mut P, dest: Dest) -> Result<()> {
    fpga_command(
        port,
        dest,
        PromCommand::new(PromOpcode::WriteEnable, 0),
        "PROM write enable",
    )?;
    Ok(())
}

/// Poll PROM_CMD until `mask` of its low bits reads 0 (up to 8 polls, 10 us
/// apart). Returns the last status.
fn wait_idle<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
    what: &'static str,
    mask: u32,
) -> Result<PromStatus> {
    for _ in 0..POLLS {
        port.wait(Duration::from_micros(10));
        let status = PromStatus(port.read_quadlet(dest, cmd_register())?);
        if status.raw() & mask == 0 {
            return Ok(status);
        }
    }
    Err(FeatureError::NotFinished { what })
}

/// The M25P16's JEDEC ID (`0x00202015`).
///
/// # Errors
/// Transaction failures; the interface never idle.
pub fn fpga_prom_id<P: Port + ?Sized>(port: &mut P, dest: Dest) -> Result<u32> {
    fpga_command(
        port,
        dest,
        PromCommand::new(PromOpcode::ReadId, 0),
        "PROM read ID",
    )
}

/// The M25P16's status byte (bit 0 WIP, bit 1 WEL).
///
/// # Errors
/// Transaction failures; the interface never idle.
pub fn fpga_prom_status<P: Port + ?Sized>(port: &mut P, dest: Dest) -> Result<u8> {
    let r = fpga_command(
        port,
        dest,
        PromCommand::new(PromOpcode::ReadStatus, 0),
        "PROM read status",
    )?;
    Ok(r as u8)
}

/// Read `out.len()` bytes (a whole number of quadlets) from PROM address
/// `address`, 64 bytes per read command (`PromReadData`).
///
/// # Errors
/// Transaction failures; a command that does not finish; a result other
/// than 64 quadlets ("incorrect number of bytes").
pub fn read_fpga_prom<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
    address: u32,
    out: &mut [u8],
) -> Result<()> {
    if out.len() % 4 != 0 {
        return Err(FeatureError::Invalid {
            what: "PROM read length must be whole quadlets",
            value: out.len() as u32,
        });
    }
    for (k, chunk) in out.chunks_mut(READ_CHUNK).enumerate() {
        let at = address.wrapping_add((k * READ_CHUNK) as u32);
        let quadlets = fpga_command(
            port,
            dest,
            PromCommand::new(PromOpcode::Read, at),
            "PROM read",
        )?;
        if 4 * quadlets != FPGA_PROM_PAGE_BYTES as u32 {
            return Err(FeatureError::Result {
                what: "PROM read: number of bytes",
                expected: FPGA_PROM_PAGE_BYTES as u32,
                found: 4 * quadlets,
            });
        }
        port.read_block(dest, FPGA_PROM_BUFFER_OFFSET, chunk)?;
    }
    Ok(())
}

/// Repeat "read status" until the whole status byte is 0 (WIP and WEL
/// clear) or only `WIP` is checked (`wip_only`).
fn wait_write_cycle<P: Port + ?Sized>(port: &mut P, dest: Dest, wip_only: bool) -> Result<()> {
    let deadline = port.now() + WRITE_CYCLE_LIMIT;
    loop {
        let status = fpga_prom_status(port, dest)?;
        let busy = if wip_only {
            status & PROM_STATUS_WIP != 0
        } else {
            status != 0
        };
        if !busy {
            return Ok(());
        }
        if port.now() > deadline {
            return Err(FeatureError::NotFinished {
                what: "PROM write cycle",
            });
        }
        port.wait(WRITE_CYCLE_POLL);
    }
}

/// Erase the 64 KiB sector containing `address` (`PromSectorErase`):
/// write enable, erase, then poll the status until it is 0.
///
/// # Errors
/// Transaction failures; a status that does not clear within 5 s.
pub fn erase_fpga_prom_sector<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
    address: u32,
) -> Result<()> {
    fpga_write_enable(port, dest)?;
    fpga_command(
        port,
        dest,
        PromCommand::new(PromOpcode::SectorErase, address),
        "PROM sector erase",
    )?;
    wait_write_cycle(port, dest, false)
}

/// Program up to 256 bytes at `address` (`PromProgramPage`): write enable,
/// one block write of the command quadlet and the data (padded to whole
/// quadlets with `0xFF`), check the stream, wait for the write cycle.
/// Returns the bytes programmed.
///
/// # Errors
/// Transaction failures; an empty or longer page; a stream error or a
/// wrong count of quadlets sent; a write cycle that does not end.
pub fn program_fpga_prom_page<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
    address: u32,
    data: &[u8],
) -> Result<usize> {
    if data.is_empty() || data.len() > FPGA_PROM_PAGE_BYTES {
        return Err(FeatureError::Invalid {
            what: "PROM page program length (1..=256 bytes)",
            value: data.len() as u32,
        });
    }
    fpga_write_enable(port, dest)?;
    let mut block = PromCommand::new(PromOpcode::PageProgram, address)
        .raw()
        .to_be_bytes()
        .to_vec();
    block.extend_from_slice(data);
    block.resize(4 + data.len().div_ceil(4) * 4, 0xFF);
    port.write_block(dest, FPGA_PROM_BUFFER_OFFSET, &block)?;
    port.wait(prom_delay(port));
    let status = wait_idle(port, dest, "PROM page program", 0xF)?;
    if status.raw() >> 24 != 0 {
        return Err(FeatureError::Result {
            what: "PROM page program stream error",
            expected: 0,
            found: status.raw() >> 16,
        });
    }
    let sent = port.read_quadlet(dest, result_register())?;
    let expected = (block.len() / 4) as u32;
    if sent != expected {
        return Err(FeatureError::Result {
            what: "PROM page program: quadlets sent",
            expected,
            found: sent,
        });
    }
    wait_write_cycle(port, dest, true)?;
    Ok(data.len())
}

/// The FPGA serial number (`GetFPGASerialNumber`): 16 bytes at
/// `0x1FFF00`, `"FPGA "` and the serial.
///
/// # Errors
/// Transaction failures; bytes without the `"FPGA "` prefix (an
/// unprogrammed PROM).
pub fn fpga_serial_number<P: Port + ?Sized>(port: &mut P, dest: Dest) -> Result<String> {
    let mut bytes = [0u8; SERIAL_IMAGE_BYTES];
    read_fpga_prom(port, dest, FPGA_SERIAL_ADDRESS, &mut bytes)?;
    Ok(parse_fpga_serial(&bytes)?.to_string())
}

/// Program the FPGA serial number as `pgm1394` does: erase the last
/// sector, program the page at `0x1FFF00`.
///
/// # Errors
/// A serial that does not fit the format; the erase or program failing.
pub fn write_fpga_serial_number<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
    serial: &str,
) -> Result<()> {
    let image = fpga_serial_image(serial)?;
    let len = (5 + serial.len()).div_ceil(4) * 4;
    erase_fpga_prom_sector(port, dest, FPGA_SERIAL_ADDRESS & 0xFF_0000)?;
    program_fpga_prom_page(port, dest, FPGA_SERIAL_ADDRESS, &image[..len])?;
    Ok(())
}

// --------------------------------------------------------------- QLA PROM ---

/// Offset of QLA PROM register `offset` (0 command, 2 result) or of the
/// buffer of `channel` (QLA1: 0; DQLA: 1 and 2).
fn qla_offset(base: u64, channel: u8) -> u64 {
    base | (u64::from(channel & 0xF) << 4)
}

/// Send QLA PROM `channel` the command `opcode` with its address and
/// value, then give the PROM its command delay.
fn qla_command<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
    channel: u8,
    opcode: QlaPromOpcode,
    address: u16,
    value: u8,
) -> Result<()> {
    port.write_quadlet(
        dest,
        qla_offset(QLA_PROM_COMMAND_OFFSET, channel),
        QlaPromCommand::new(opcode, address, value).raw(),
    )?;
    port.wait(prom_delay(port));
    Ok(())
}

/// Read one byte of QLA PROM `channel` (QLA1: 0; DQLA: 1, 2).
///
/// # Errors
/// Transaction failures.
pub fn read_qla_prom_byte<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
    channel: u8,
    address: u16,
) -> Result<u8> {
    qla_command(port, dest, channel, QlaPromOpcode::ReadByte, address, 0)?;
    let r = port.read_quadlet(dest, qla_offset(QLA_PROM_RESULT_OFFSET, channel))?;
    Ok(r as u8)
}

/// Write one byte: write enable, 100 us, the byte, 5 ms for the write
/// cycle (the host does not poll).
///
/// # Errors
/// Transaction failures.
pub fn write_qla_prom_byte<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
    channel: u8,
    address: u16,
    value: u8,
) -> Result<()> {
    qla_command(port, dest, channel, QlaPromOpcode::WriteEnable, 0, 0)?;
    port.wait(Duration::from_micros(100));
    qla_command(
        port,
        dest,
        channel,
        QlaPromOpcode::WriteByte,
        address,
        value,
    )?;
    port.wait(Duration::from_millis(5));
    Ok(())
}

fn check_block(len: usize) -> Result<u8> {
    if len == 0 || len % 4 != 0 || len > 4 * QLA_PROM_BUFFER_QUADLETS {
        return Err(FeatureError::Invalid {
            what: "QLA PROM block length (4..=64 bytes, whole quadlets)",
            value: len as u32,
        });
    }
    Ok((len / 4 - 1) as u8)
}

/// Read `out.len()` bytes (4..=64, whole quadlets) from `address` into the
/// buffer, then block-read it.
///
/// # Errors
/// Transaction failures; a bad length.
pub fn read_qla_prom_block<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
    channel: u8,
    address: u16,
    out: &mut [u8],
) -> Result<()> {
    let n = check_block(out.len())?;
    qla_command(port, dest, channel, QlaPromOpcode::ReadBlock, address, n)?;
    port.read_block(dest, qla_offset(QLA_PROM_BUFFER_OFFSET, channel), out)?;
    Ok(())
}

/// Write `data` (4..=64 bytes, whole quadlets, one 64-byte page) at
/// `address`: block write to the buffer, write enable, the page write,
/// 5 ms for the write cycle.
///
/// # Errors
/// Transaction failures; a bad length.
pub fn write_qla_prom_block<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
    channel: u8,
    address: u16,
    data: &[u8],
) -> Result<()> {
    let n = check_block(data.len())?;
    port.write_block(dest, qla_offset(QLA_PROM_BUFFER_OFFSET, channel), data)?;
    qla_command(port, dest, channel, QlaPromOpcode::WriteEnable, 0, 0)?;
    qla_command(port, dest, channel, QlaPromOpcode::WriteBlock, address, n)?;
    port.wait(Duration::from_millis(5));
    Ok(())
}

/// The QLA serial number of QLA `channel` (`GetQLASerialNumber`: 12
/// bytes from address 0, `"QLA "` and the serial).
///
/// # Errors
/// Transaction failures; bytes without the `"QLA "` prefix.
pub fn qla_serial_number<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
    channel: u8,
) -> Result<String> {
    let mut bytes = [0u8; QLA_SERIAL_READ_BYTES];
    read_qla_prom_block(port, dest, channel, 0, &mut bytes)?;
    Ok(parse_qla_serial(&bytes)?.to_string())
}

/// Write the QLA serial number byte by byte, as the tools do (`"QLA "`,
/// the serial, a terminating 0).
///
/// # Errors
/// A serial that does not fit the format; transaction failures.
pub fn write_qla_serial_number<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
    channel: u8,
    serial: &str,
) -> Result<()> {
    let image = qla_serial_image(serial)?;
    for (address, b) in image.iter().take(4 + serial.len() + 1).enumerate() {
        write_qla_prom_byte(port, dest, channel, address as u16, *b)?;
    }
    Ok(())
}
