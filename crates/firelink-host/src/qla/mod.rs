//! The QLA family's wing: boards built from an FPGA1394 (V1 to V3) and a
//! QLA or DQLA power board, as the dVRK uses them. Beside `snake/` and
//! `mahru/`, which hold the other robots' node protocols.
//!
//! - [`scan`]: discovery (the boards behind a port, what they are) and
//!   the choice of the I/O protocol they all support;
//! - [`board`]: one board's registers and features, read and written by
//!   name (status, power, amplifiers, watchdog, DACs, digital I/O);
//! - [`io`]: the I/O system a servo loop runs on, every board in one read
//!   and one write phase (sequential or broadcast);
//! - [`extras`]: what a board offers beside servo I/O (PROM, the tool's
//!   Dallas chip, digital outputs, the motor supply, the Ethernet chip);
//! - [`board_access`] and [`register_address`]: the bus tools' work on
//!   boards (`firelink scan`, `info`, `read`, `write`), registers by name
//!   and the board's address map;
//! - [`monitor`] and [`monitor_frame`]: the live view of every board
//!   (`firelink monitor`), its switches and its screen;
//! - [`tour`]: one broadcast I/O cycle packet by packet (`firelink tour`).
//!
//! What every robot shares (ports, transactions, the `RobotIo` trait,
//! the cycle's report and counters, errors) stays at the crate's root.

pub mod board;
pub mod board_access;
pub mod extras;
pub mod io;
pub mod monitor;
pub mod monitor_frame;
pub mod register_address;
pub mod scan;
pub mod tour;
