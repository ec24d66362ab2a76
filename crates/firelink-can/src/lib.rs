//! # firelink-can: a CAN 2.0A bus model in virtual time
//!
//! Seed 002 compares its IEEE 1394 humanoid with a CAN-based one (Table
//! IV: 10.5 ms per exchange on CAN at 1 Mb/s against about 60 us per 1394
//! read). To explain that ratio from first principles Firelink needs CAN
//! as well as 1394, at the same level of detail:
//!
//! - [`frame`]: standard frames at the bit level: identifier, control
//!   field, data, the CRC-15, bit stuffing and the exact bit count of a
//!   frame, beside the worst-case formula;
//! - [`bus`]: a bus in virtual time: arbitration by identifier, frames for
//!   their exact duration, error frames and retransmission, fault
//!   confinement.
//!
//! No I/O, no clock; random errors come from a seeded RNG.
//!
//! ```
//! use core::time::Duration;
//! use firelink_can::bus::{CanBus, CanConfig};
//! use firelink_can::frame::{CanId, Frame};
//! let mut bus = CanBus::new(CanConfig::default()).unwrap();
//! let a = bus.add_node("a");
//! let b = bus.add_node("b");
//! // Both ready at once: the lower identifier goes first.
//! bus.submit(a, Frame::data(CanId::new(0x200).unwrap(), &[1; 8]).unwrap(), Duration::ZERO).unwrap();
//! bus.submit(b, Frame::data(CanId::new(0x100).unwrap(), &[2; 8]).unwrap(), Duration::ZERO).unwrap();
//! let done = bus.run_until_idle();
//! assert_eq!(done[0].node, b);
//! assert_eq!(done[1].lost_arbitration, 1);
//! // An 8-byte frame takes 111 bits plus its stuff bits: at most 135 us at 1 Mb/s.
//! assert!(done[0].bus_free_at <= Duration::from_micros(135));
//! ```

pub mod bus;
pub mod frame;

/// What the CAN model refuses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum CanError {
    /// An identifier above 0x7FF.
    #[error("identifier {0:#x} does not fit 11 bits")]
    Identifier(u16),
    /// More than 8 data bytes.
    #[error("{0} data bytes: a CAN 2.0 frame carries at most 8")]
    Length(usize),
    /// A node index not on the bus.
    #[error("no node {0} on the bus")]
    NoSuchNode(usize),
    /// A configuration value out of range.
    #[error("configuration: {0}")]
    Config(&'static str),
}

/// Result alias of the CAN model.
pub type Result<T> = core::result::Result<T, CanError>;
