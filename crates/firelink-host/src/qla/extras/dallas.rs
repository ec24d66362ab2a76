//! The DS2505 instrument memory through the QLA's 1-wire interface
//! (`fpga-board-extras.md` §4): the dVRK's `DallasReadTool` and the tools'
//! `DallasReadMemory`.

use std::time::Duration;

use firelink_wire::qla::address::BoardRegister;
use firelink_wire::qla::extras::{
    DALLAS_BUFFER_OFFSET, DS2505_BYTES, DallasControl, DallasMode, DallasReset, DallasStatus,
};

use super::{FeatureError, Result, board_register};
use crate::port::{Dest, Port};

/// Bytes the interface reads per command.
const CHUNK: usize = 256;
/// Where a tool's record starts (the `"997"` marker).
const TOOL_RECORD: u16 = 0x80;
/// How long the host waits for the interface (the dVRK's 10 s).
const IDLE_LIMIT: Duration = Duration::from_secs(10);
/// Pause between polls.
const POLL: Duration = Duration::from_millis(1);
/// DSSTAT bits that say the interface is working (busy, state).
const WORKING: u32 = 0x20F0;

/// What a tool's DS2505 says about it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ToolInfo {
    /// Model number (24 bits).
    pub model: u32,
    /// Version.
    pub version: u8,
    /// Name.
    pub name: String,
}

/// Register 13 as read.
///
/// # Errors
/// Transaction failures.
pub fn dallas_status<P: Port + ?Sized>(port: &mut P, dest: Dest) -> Result<DallasStatus> {
    Ok(DallasStatus(port.read_quadlet(
        dest,
        board_register(BoardRegister::DallasStatus),
    )?))
}

fn write_control<P: Port + ?Sized>(port: &mut P, dest: Dest, c: DallasControl) -> Result<()> {
    port.write_quadlet(dest, board_register(BoardRegister::DallasStatus), c.raw())?;
    Ok(())
}

/// Poll register 13 until the interface is idle.
fn wait_idle<P: Port + ?Sized>(port: &mut P, dest: Dest) -> Result<DallasStatus> {
    let deadline = port.now() + IDLE_LIMIT;
    loop {
        let s = dallas_status(port, dest)?;
        if s.raw() & WORKING == 0 {
            return Ok(s);
        }
        if port.now() > deadline {
            return Err(FeatureError::NotFinished {
                what: "DS2505 read",
            });
        }
        port.wait(POLL);
    }
}

/// After a read that used a DS2480B: end its session and wait.
fn end_session<P: Port + ?Sized>(port: &mut P, dest: Dest, status: DallasStatus) -> Result<()> {
    if status.ds2480b() {
        write_control(
            port,
            dest,
            DallasControl::default()
                .with_end_session(true)
                .with_mode_bits(1),
        )?;
        wait_idle(port, dest)?;
    }
    Ok(())
}

fn check_present(status: DallasStatus) -> Result<()> {
    match status.reset() {
        DallasReset::Answered => Ok(()),
        DallasReset::NoPresence => Err(FeatureError::Unavailable {
            what: "instrument",
            why: "no presence pulse on the 1-wire line (no tool)",
        }),
        DallasReset::NoRise => Err(FeatureError::Unavailable {
            what: "instrument",
            why: "the 1-wire line does not rise (missing pull-up)",
        }),
        _ => Err(FeatureError::Unavailable {
            what: "instrument",
            why: "the 1-wire interface did not reset the line",
        }),
    }
}

/// Read `out.len()` bytes (a multiple of 256, at most 2048) from address
/// `address` (`DallasReadMemory`): a first read, then next reads.
///
/// # Errors
/// Transaction failures; no instrument; a bad length.
pub fn read_dallas_memory<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
    address: u16,
    out: &mut [u8],
) -> Result<()> {
    if out.is_empty() || out.len() % CHUNK != 0 || out.len() > DS2505_BYTES {
        return Err(FeatureError::Invalid {
            what: "DS2505 read length (a multiple of 256, up to 2048)",
            value: out.len() as u32,
        });
    }
    let mut status = DallasStatus::default();
    for (k, chunk) in out.chunks_mut(CHUNK).enumerate() {
        let c = if k == 0 {
            DallasControl::default()
                .with_address(address)
                .with_mode_bits(DallasMode::ReadFirst.into())
        } else {
            DallasControl::default().with_mode_bits(DallasMode::ReadNext.into())
        };
        write_control(port, dest, c)?;
        status = wait_idle(port, dest)?;
        check_present(status)?;
        port.read_block(dest, DALLAS_BUFFER_OFFSET, chunk)?;
    }
    end_session(port, dest, status)
}

/// Read the tool's record as the dVRK does (`DallasReadTool`): 256 bytes
/// from `0x80`, `"997"` first, the model at `0xA4` (24 bits), the version
/// at `0xA8`, the name at `0x160`.
///
/// # Errors
/// Transaction failures; no instrument; a record without `"997"`.
pub fn read_tool<P: Port + ?Sized>(port: &mut P, dest: Dest) -> Result<ToolInfo> {
    let mut record = [0u8; CHUNK];
    read_dallas_memory(port, dest, TOOL_RECORD, &mut record)?;
    if record.get(..3) != Some(b"997") {
        let marker = u32::from_be_bytes([0, record[0], record[1], record[2]]);
        return Err(FeatureError::Result {
            what: "tool record marker \"997\"",
            expected: 0x39_3937,
            found: marker,
        });
    }
    let at = |a: usize| a - usize::from(TOOL_RECORD);
    let model = u32::from_be_bytes([0, record[at(0xA5)], record[at(0xA6)], record[at(0xA7)]]);
    let version = record[at(0xA8)];
    let name: String = record[at(0x160)..at(0x17B)]
        .iter()
        .take_while(|b| **b != 0)
        .map(|b| char::from(*b))
        .collect();
    Ok(ToolInfo {
        model,
        version,
        name,
    })
}
