//! The MAHRU humanoid's module protocol (seed 002): custom commands carried
//! in standard 1394 asynchronous packets.
//!
//! Facts: `seed-systems.md` section C and seed 002 section III.C, Fig. 7,
//! Table II. The destination offset of a request is the *command field*:
//! its value is the command code ([`Command`]). Point-to-point commands go
//! to a module's node ID; broadcast commands go to node 63 on the local
//! bus (`0xFFFF`). Because node IDs change at every bus reset, each module
//! has a module ID ([`ModId`]) of its own, which the host maps to the
//! current node ID with IDREQUEST and IDCHECK after every reset.
//!
//! | code | command | sent as | payload |
//! |---|---|---|---|
//! | 0 | STOP | broadcast quadlet write | [`ModMask`] |
//! | 11 | IDREQUEST | P2P quadlet read | answer: [`Identity`] |
//! | 12 | IDCHECK | P2P quadlet read | answer: [`IdCheck`] |
//! | 13 | PARAMETER | P2P or broadcast block write | [`ParameterRecord`]s |
//! | 14 | SETBIAS | broadcast quadlet write | [`ModMask`] |
//! | 15 | READY | broadcast quadlet write | [`ModMask`] |
//! | 16 | START | broadcast quadlet write | [`ModMask`] |
//! | 17 | QREAD | P2P block read, 32 bytes | answer: [`JointBlock`] |
//! | 18 | QWRITE | broadcast block write, 320 bytes | 10 [`SetpointSlot`]s |
//! | 19 | FTREAD | P2P block read, 24 bytes | answer: [`FtBlock`] |
//!
//! **Source ID.** Seed 002 fills the source ID with the node ID or the
//! ModID "depending on the type of operation", and with 0x3F (the local
//! bus's broadcast physical ID) in the computer's broadcasts. Here a
//! module's *responses* carry its node ID, because that is what the
//! computer's link matches responses by (with the transaction label), as
//! an OHCI link does; the ModID travels in the data of every answer that
//! identifies a module (IDREQUEST, IDCHECK, QREAD). Modules take broadcast
//! commands from any source, so a computer that writes 0xFFFF (bus 0x3FF,
//! node 0x3F) there, as the seed's does, is obeyed like one that writes its
//! own node ID.
//!
//! The seed gives the codes, the transaction types and the sizes (24 B
//! from a sensor module, 32 B from a motor controller, 320 B of set-points
//! for 10 controllers); it does not print the field layouts inside the
//! blocks. The layouts here are Firelink's, chosen to carry what the seed
//! says each block holds (joint position and velocity, force and torque,
//! gear ratio and PID gains) in whole quadlets, big-endian like every 1394
//! payload. Physical quantities are fixed-point integers: positions in
//! microradians, velocities in microradians per second, accelerations in
//! milliradians per second squared, currents in milliamperes, forces in
//! millinewtons, torques in millinewton-metres. Parameters are IEEE 754
//! single-precision floats (the modules' TMS320VC33 is a floating-point DSP).
//!
//! Every parser checks the length first and rejects values without meaning
//! with an [`Error`] naming the field; after a successful parse nothing
//! panics. Unknown command codes and states are data ([`Command::Unknown`],
//! [`ModuleState::Unknown`]): a module ignores a command it does not know.
//!
//! Private submodules, re-exported here: `commands` (codes, IDs, masks,
//! states), `identity` (IDREQUEST and IDCHECK answers), `blocks` (QREAD and
//! FTREAD answers), `setpoints` (QWRITE) and `parameter` (PARAMETER).
//!
//! ```
//! use firelink_wire::mahru::{Command, JointBlock, ModId, ModuleState};
//! assert_eq!(Command::from_offset(17), Some(Command::QRead));
//! assert!(Command::QWrite.is_broadcast());
//! let block = JointBlock {
//!     mod_id: ModId(3),
//!     state: ModuleState::Running,
//!     sequence: 42,
//!     position_urad: -150_000,
//!     velocity_urad_s: 20_000,
//!     current_ma: 1200,
//!     target_urad: -149_000,
//!     torque_mnm: 3500,
//!     servo_ticks: 1000,
//!     flags: JointBlock::AMPLIFIER_ON,
//! };
//! let mut buf = [0xA5u8; JointBlock::LEN];
//! block.emit(&mut buf).unwrap();
//! assert_eq!(JointBlock::parse(&buf).unwrap(), block);
//! ```

use crate::field::{Field, read_quadlet, write_quadlet};
use crate::open_enum::open_enum;
use crate::{Error, Result};

/// Largest value of a 4-bit state field.
const STATE_MAX: u8 = 0xF;

fn state_from_bits(bits: u32) -> ModuleState {
    ModuleState::from(bits as u8)
}

fn state_bits(state: ModuleState) -> Result<u32> {
    let raw = u8::from(state);
    if raw > STATE_MAX {
        return Err(Error::FieldRange {
            field: "module state",
            value: u64::from(raw),
            max: u64::from(STATE_MAX),
        });
    }
    Ok(u32::from(raw))
}

/// Check that `buf` holds exactly `len` bytes of a block.
fn check_len(what: &'static str, buf: &[u8], len: usize) -> Result<()> {
    if buf.len() < len {
        return Err(Error::Truncated {
            what,
            needed: len,
            available: buf.len(),
        });
    }
    if buf.len() > len {
        return Err(Error::TrailingBytes {
            what,
            extra: buf.len() - len,
        });
    }
    Ok(())
}

/// The first `len` bytes of an output buffer.
fn out_slice<'a>(what: &'static str, buf: &'a mut [u8], len: usize) -> Result<&'a mut [u8]> {
    let available = buf.len();
    buf.get_mut(..len).ok_or(Error::BufferTooSmall {
        what,
        needed: len,
        available,
    })
}

mod blocks;
mod commands;
mod identity;
mod parameter;
mod setpoints;

pub use blocks::*;
pub use commands::*;
pub use identity::*;
pub use parameter::*;
pub use setpoints::*;
