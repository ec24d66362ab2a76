//! The QLA family's wing: boards built from an FPGA1394 (V1 to V3) and a
//! QLA or DQLA power board, as the dVRK uses them. Beside `snake/` and
//! `mahru/`, which hold the other robots' node protocols.
//!
//! - [`board`]: one board's registers and features, read and written by
//!   name (status, power, amplifiers, watchdog, DACs, digital I/O);
//! - [`io`]: the I/O system a servo loop runs on, every board in one read
//!   and one write phase (sequential or broadcast);
//! - [`extras`]: what a board offers beside servo I/O (PROM, the tool's
//!   Dallas chip, digital outputs, the motor supply, the Ethernet chip).
//!
//! What every robot shares (ports, transactions, scans, the `RobotIo`
//! trait, errors) stays at the crate's root.

pub mod board;
pub mod extras;
pub mod io;
