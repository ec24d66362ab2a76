//! Virtual time as the boards see it: the simulated bus's picoseconds
//! ([`SimTime`], [`SimDuration`]), and the FPGA's 49.152 MHz system clock
//! ([`SYSTEM_CLOCK_HZ`]) counted from them ([`SimTime::clocks`],
//! [`SimDuration::from_clocks`]).
//!
//! One definition, one name: these are the bus's own types
//! ([`firelink_bus::time`]), re-exported here for the board code. Nothing
//! in this crate reads a clock: every entry point takes `now`.

pub use firelink_bus::time::{PS_PER_S, SYSTEM_CLOCK_HZ, SimDuration, SimTime};

/// One watchdog tick: 256 system clocks, about 5.208 us (`fpga-board.md`
/// section 2, register 3; defined with the register,
/// [`Watchdog::CLOCKS_PER_TICK`](firelink_wire::qla::registers::Watchdog::CLOCKS_PER_TICK)).
pub const WATCHDOG_TICK_CLOCKS: u64 =
    firelink_wire::qla::registers::Watchdog::CLOCKS_PER_TICK as u64;
