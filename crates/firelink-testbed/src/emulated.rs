//! The emulated hardware's types that front ends name (the CLI's
//! `emulate` and `sim` options, Python's arguments): board configurations
//! and firmware profiles from [`firelink_board`], the bus's fault rules,
//! durations and arbitration classes from [`firelink_bus`]. Front ends
//! reach the layers below through the testbed only, so that they depend
//! on one crate for emulated robots.

pub use firelink_board::qla::config::{
    BoardConfig, BoardSettings, ConfigError, FpgaVersion, Hardware, Profile, default_fpga_serial,
    default_qla_serial,
};
pub use firelink_bus::{ArbitrationClass, FaultRule, PacketFault, PacketMatch, SimDuration};
