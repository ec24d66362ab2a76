//! Virtual time as the boards see it: the simulated bus's picoseconds
//! ([`firelink_bus::time`]), and the FPGA's 49.152 MHz system clock counted
//! from them ([`Time::clocks`], [`TimeDelta::from_clocks`]).
//!
//! One definition: [`Time`] and [`TimeDelta`] are the bus's
//! [`SimTime`](firelink_bus::SimTime) and
//! [`SimDuration`](firelink_bus::SimDuration) under the names the board's
//! firmware and plant code use. Nothing in this crate reads a clock: every
//! entry point takes `now`.

pub use firelink_bus::time::{
    PS_PER_S as PS_PER_SECOND, SYSTEM_CLOCK_HZ as SYSCLK_HZ, SimDuration as TimeDelta,
    SimTime as Time,
};

/// One watchdog tick: 256 system clocks, about 5.208 us (`fpga-board.md`
/// section 2, register 3; defined with the register,
/// [`Watchdog::CLOCKS_PER_TICK`](firelink_wire::board::registers::Watchdog::CLOCKS_PER_TICK)).
pub const WATCHDOG_TICK_CLOCKS: u64 =
    firelink_wire::board::registers::Watchdog::CLOCKS_PER_TICK as u64;
