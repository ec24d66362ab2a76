//! The identifiers the trace and the fault log share.

/// A packet's number in the trace, in order of transmission.
pub type PacketId = u64;

/// A fault's number in the fault log, in order of injection.
pub type FaultId = u32;
