//! # firelink-board: emulated FPGA1394 + QLA motor-controller boards
//!
//! Software boards that behave on the wire like the public FPGA1394 + QLA
//! (and DQLA) firmware, revisions 7 and 8, and like the seed-000 era
//! broadcast firmware, with a deterministic physical plant behind them.
#![cfg_attr(not(test), warn(clippy::indexing_slicing))]

pub mod config;
pub mod firmware;
pub mod plant;
pub mod time;
