//! Register addresses as people write them (`status`, `hw_version`,
//! `axis2.enc_position`) and the board's address map they must lie in, for
//! every front end that reads or writes registers by hand.
//!
//! Rules:
//! - a name is matched without regard to case, `-` or `_` against the
//!   known registers of [`BoardRegister`] and [`AxisRegister`];
//! - an address is checked against the board's map before anything is
//!   sent: the board decodes only the low 16 bits of an offset, so an
//!   address beyond `0xffff` would silently alias, and one beyond 48 bits
//!   is no 1394 offset at all.

use firelink_wire::qla::address::{AxisRegister, BoardRegister, Register};

/// The largest 1394 offset: 48 bits.
pub const MAX_1394_OFFSET: u64 = 0xFFFF_FFFF_FFFF;

/// The board decodes the low 16 bits of an offset (`fpga-board.md` §1):
/// its whole address map, every space, is `0x0000..=0xFFFF`.
pub const MAX_BOARD_ADDRESS: u64 = 0xFFFF;

/// Why a register name or address cannot be used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum AddressError {
    /// A register name that is not on the board.
    #[error("register {name:?}: {problem}")]
    Register {
        /// What was given.
        name: String,
        /// What is wrong with it.
        problem: &'static str,
    },
    /// An address outside the board's map.
    #[error("address {address:#x}: {problem}")]
    Address {
        /// The address given.
        address: u64,
        /// Why it cannot be used.
        problem: String,
    },
    /// The register exists but has no offset (the wire layer says why).
    #[error(transparent)]
    Wire(#[from] firelink_wire::Error),
}

/// The offset of a register named `name` or `axisN.name`.
///
/// # Errors
/// [`AddressError::Register`] for a name that is not a known register (or
/// a malformed `axisN.`); [`AddressError::Wire`] for an axis beyond the
/// map.
pub fn register_offset(name: &str) -> Result<u64, AddressError> {
    let lower = name.to_ascii_lowercase().replace('-', "_");
    let refused = |problem| AddressError::Register {
        name: name.to_string(),
        problem,
    };
    let register = if let Some(rest) = lower.strip_prefix("axis") {
        let (n, reg) = rest
            .split_once('.')
            .ok_or_else(|| refused("expected axisN.name"))?;
        let n: u8 = n.parse().map_err(|_| refused("bad axis number"))?;
        let r = (0u8..16)
            .map(AxisRegister::from)
            .find(|r| r.is_known() && same_name(&format!("{r:?}"), reg))
            .ok_or_else(|| refused("no such axis register"))?;
        Register::axis(n, r)
    } else {
        let r = (0u8..16)
            .map(BoardRegister::from)
            .find(|r| r.is_known() && same_name(&format!("{r:?}"), &lower))
            .ok_or_else(|| refused("no such board register"))?;
        Register::board(r)
    };
    Ok(register.offset()?)
}

/// Whether a register's Rust name and a name as written are the same
/// (case, `_` and `-` aside).
fn same_name(rust_name: &str, written: &str) -> bool {
    rust_name.to_ascii_lowercase() == written.replace('_', "")
}

/// `quadlets` quadlets from `address` must lie in the board's map.
///
/// # Errors
/// [`AddressError::Address`] saying which limit and what it would have
/// reached.
pub fn check_address(address: u64, quadlets: usize) -> Result<(), AddressError> {
    let last = address.saturating_add(quadlets.saturating_sub(1) as u64);
    let problem = if address > MAX_1394_OFFSET {
        format!("beyond the 48-bit 1394 offset space (at most {MAX_1394_OFFSET:#x})")
    } else if address > MAX_BOARD_ADDRESS {
        format!(
            "beyond the board's address map 0x0000..=0xffff (the board decodes only the \
             low 16 bits of an offset: this would reach {:#06x})",
            address & MAX_BOARD_ADDRESS
        )
    } else if last > MAX_BOARD_ADDRESS {
        format!(
            "{quadlets} quadlets from here run past the end of the board's address map \
             (0xffff)"
        )
    } else {
        return Ok(());
    };
    Err(AddressError::Address { address, problem })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn register_names() {
        assert_eq!(register_offset("status"), Ok(0));
        assert_eq!(register_offset("hw_version"), Ok(4));
        assert_eq!(register_offset("HW-Version"), Ok(4));
        assert_eq!(register_offset("axis2.enc_position"), Ok(0x25));
        let e = register_offset("bogus").unwrap_err().to_string();
        assert_eq!(e, "register \"bogus\": no such board register");
        let e = register_offset("axis2.bogus").unwrap_err().to_string();
        assert_eq!(e, "register \"axis2.bogus\": no such axis register");
        let e = register_offset("axis2").unwrap_err().to_string();
        assert_eq!(e, "register \"axis2\": expected axisN.name");
        let e = register_offset("axisx.status").unwrap_err().to_string();
        assert_eq!(e, "register \"axisx.status\": bad axis number");
    }

    #[test]
    fn addresses_beyond_the_map_are_refused() {
        assert!(check_address(0, 1).is_ok());
        assert!(check_address(0x1000, 512).is_ok());
        assert!(check_address(0xFFFF, 1).is_ok());
        let e = check_address(0x1_0000_0000, 1).unwrap_err().to_string();
        assert!(
            e.starts_with("address 0x100000000: beyond the board's address map"),
            "{e}"
        );
        assert!(e.contains("0x0000"), "{e}");
        let e = check_address(0x1_0000_0000_0000, 1)
            .unwrap_err()
            .to_string();
        assert!(e.contains("48-bit"), "{e}");
        let e = check_address(0xFFFF, 2).unwrap_err().to_string();
        assert!(e.contains("run past the end"), "{e}");
        assert!(check_address(u64::MAX, 512).is_err());
    }
}
