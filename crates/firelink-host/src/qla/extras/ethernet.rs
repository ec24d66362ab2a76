//! The Ethernet side of an FPGA V2 (`fpga-board-extras.md` §6): KSZ8851
//! registers through register 12 (`ReadKSZ8851Reg`) and the debug window
//! of space 4.

use firelink_wire::qla::address::BoardRegister;
use firelink_wire::qla::extras::{ETH_DEBUG_ABSENT, ETH_WINDOW_OFFSET, EthControl, EthStatusV2};

use super::{FeatureError, Result, board_register};
use crate::port::{Dest, Port};

/// Register 12 as an FPGA V2 reads it.
///
/// # Errors
/// Transaction failures.
pub fn eth_status<P: Port + ?Sized>(port: &mut P, dest: Dest) -> Result<EthStatusV2> {
    Ok(EthStatusV2(port.read_quadlet(
        dest,
        board_register(BoardRegister::EthStatus),
    )?))
}

/// Read a 16-bit KSZ8851 register: write the request to register 12, read
/// it back, require Ethernet present and no request error.
///
/// # Errors
/// Transaction failures; [`FeatureError::Unavailable`] on a board without
/// Ethernet or when the KSZ refused the request.
pub fn read_ksz8851_register<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
    register: u8,
) -> Result<u16> {
    let r = board_register(BoardRegister::EthStatus);
    port.write_quadlet(dest, r, EthControl::read_word(register).raw())?;
    let s = EthStatusV2(port.read_quadlet(dest, r)?);
    if !s.present() {
        return Err(FeatureError::Unavailable {
            what: "KSZ8851 register",
            why: "no Ethernet on this board",
        });
    }
    if s.ksz_request_error() {
        return Err(FeatureError::Unavailable {
            what: "KSZ8851 register",
            why: "the KSZ8851 refused the request",
        });
    }
    Ok(s.data())
}

/// Read `out.len()` quadlets (at most 64) of the debug window from
/// `first` (0..=255).
///
/// # Errors
/// Transaction failures; more than 64 quadlets.
pub fn read_eth_window<P: Port + ?Sized>(
    port: &mut P,
    dest: Dest,
    first: u8,
    out: &mut [u32],
) -> Result<()> {
    if out.is_empty() || out.len() > 64 {
        return Err(FeatureError::Invalid {
            what: "debug window read (1..=64 quadlets)",
            value: out.len() as u32,
        });
    }
    let mut bytes = [0u8; 256];
    let buf = &mut bytes[..out.len() * 4];
    port.read_block(dest, ETH_WINDOW_OFFSET + u64::from(first), buf)?;
    for (q, c) in out.iter_mut().zip(buf.chunks_exact(4)) {
        *q = u32::from_be_bytes([c[0], c[1], c[2], c[3]]);
    }
    Ok(())
}

/// Whether the board was built with Ethernet debug data: the header at
/// `0x4080` reads `"DBG2"` with it, `"DBG0"` without (a Rev 8 V2).
///
/// # Errors
/// Transaction failures; a header that is neither ("should be DBG").
pub fn has_eth_debug_data<P: Port + ?Sized>(port: &mut P, dest: Dest) -> Result<bool> {
    let mut header = [0u32; 1];
    read_eth_window(port, dest, 0x80, &mut header)?;
    match header[0] {
        ETH_DEBUG_ABSENT => Ok(false),
        0x3247_4244 => Ok(true),
        other => Err(FeatureError::Result {
            what: "Ethernet debug header (should be DBG)",
            expected: ETH_DEBUG_ABSENT,
            found: other,
        }),
    }
}
