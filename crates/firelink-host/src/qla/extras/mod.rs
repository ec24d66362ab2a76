//! The firmware features beyond the servo cycle, driven as the reference
//! host drives them (`fpga-board-extras.md`): the PROMs and serial numbers,
//! the digital outputs and waveform table, the DS2505 instrument memory,
//! the I/O expander, the Ethernet registers of an FPGA V2, the motor
//! supply measurement and the PHY registers.
//!
//! Every function takes any [`Port`] and the board's
//! [`Dest`], sends the same request sequence as the reference
//! host library and waits with [`Port::wait`] (virtual
//! time on the simulated bus). Over the Ethernet bridge, whose writes are
//! not acknowledged, a PROM command is given the reference host's 1 ms
//! (`PromDelay`) before its result is read.
//!
//! ```
//! # #[cfg(feature = "sim")] {
//! use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
//! use firelink_board::qla::rig::{BoardRig, RigOptions};
//! use firelink_host::qla::extras::prom::{fpga_serial_number, qla_serial_number};
//! use firelink_host::sim::SimPort;
//! use firelink_host::Dest;
//! let board = BoardConfig::new(3, Hardware::Qla1, Profile::Rev8)
//!     .with_fpga_serial("4981-03")
//!     .with_qla_serial(0, "4980-03");
//! let rig = BoardRig::daisy_chain(vec![board], &RigOptions::default());
//! let mut port = SimPort::new(rig.bus, rig.host);
//! let board = Dest::node(0);
//! assert_eq!(fpga_serial_number(&mut port, board).unwrap(), "4981-03");
//! assert_eq!(qla_serial_number(&mut port, board, 0).unwrap(), "4980-03");
//! # }
//! ```

pub mod dallas;
pub mod dout;
pub mod ethernet;
pub mod prom;
pub mod supply;

use std::time::Duration;

use firelink_wire::qla::address::{BoardRegister, Register};
use firelink_wire::qla::registers::{PhyData, PhyRequest};

use crate::error::HostError;
use crate::port::{Dest, Port};

/// Why a firmware feature could not be used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum FeatureError {
    /// The transaction itself failed.
    #[error(transparent)]
    Host(#[from] HostError),
    /// The board did not finish a command in the time the host gives it.
    #[error("{what}: command failed to finish")]
    NotFinished {
        /// The command.
        what: &'static str,
    },
    /// A result register holds what the command cannot give.
    #[error("{what}: expected {expected:#x}, read {found:#x}")]
    Result {
        /// What was checked.
        what: &'static str,
        /// The value the command gives.
        expected: u32,
        /// The value read.
        found: u32,
    },
    /// Data read from the board is not in the expected format.
    #[error("{0}")]
    Format(firelink_wire::Error),
    /// The board lacks what the feature needs.
    #[error("{what} not available: {why}")]
    Unavailable {
        /// The feature.
        what: &'static str,
        /// What is missing.
        why: &'static str,
    },
    /// A request the board cannot take.
    #[error("invalid request: {what} (value {value})")]
    Invalid {
        /// What is wrong.
        what: &'static str,
        /// The offending value.
        value: u32,
    },
}

impl From<firelink_wire::Error> for FeatureError {
    fn from(e: firelink_wire::Error) -> Self {
        FeatureError::Format(e)
    }
}

/// Result alias of the features.
pub type Result<T> = core::result::Result<T, FeatureError>;

/// The main-space offset of a board register.
pub(crate) fn board_register(r: BoardRegister) -> u64 {
    // Board registers are 0..=15: their offset always exists.
    Register::board(r).offset().unwrap_or(0)
}

/// The reference host's `PromDelay`: 1 ms over the Ethernet bridge (whose
/// writes are not acknowledged), none on FireWire.
pub fn prom_delay<P: Port + ?Sized>(port: &P) -> Duration {
    if port.acknowledges_writes() {
        Duration::ZERO
    } else {
        Duration::from_millis(1)
    }
}

/// Read PHY register `register` (0..=15) of the board's PHY as fpgatest
/// `f` does: write the number to PHY_CTRL, read PHY_DATA, require bits
/// 11:8 to name the register (`fpga-board-extras.md` §8).
///
/// # Errors
/// Transaction failures; [`FeatureError::Result`] when PHY_DATA names
/// another register.
pub fn read_phy_register<P: Port + ?Sized>(port: &mut P, dest: Dest, register: u8) -> Result<u8> {
    let request = PhyRequest::Read {
        register: register & 0xF,
    }
    .to_word()?;
    port.write_quadlet(dest, board_register(BoardRegister::PhyCtrl), request)?;
    let data = PhyData(port.read_quadlet(dest, board_register(BoardRegister::PhyData))?);
    if data.register() != register & 0xF {
        return Err(FeatureError::Result {
            what: "PHY_DATA register number",
            expected: u32::from(register & 0xF),
            found: u32::from(data.register()),
        });
    }
    Ok(data.data())
}

/// Whether the board's QLA has the I/O expander (STATUS bit 12, QLA 1.5+;
/// the host's `IsQLAExpanded`).
///
/// # Errors
/// Transaction failures.
pub fn is_qla_expanded<P: Port + ?Sized>(port: &mut P, dest: Dest) -> Result<bool> {
    let status = port.read_quadlet(dest, board_register(BoardRegister::Status))?;
    Ok(firelink_wire::qla::registers::StatusRead(status).io_expander())
}

/// Send one MAX7317 command through register 14 and read register 14
/// straight after, as fpgatest `m` does (`fpga-board-extras.md` §5).
///
/// # Errors
/// Transaction failures.
pub fn expander_command<P: Port + ?Sized>(port: &mut P, dest: Dest, word: u32) -> Result<u32> {
    let r = board_register(BoardRegister::IoExpander);
    port.write_quadlet(dest, r, word)?;
    Ok(port.read_quadlet(dest, r)?)
}
