//! Seed 002 in full: the MAHRU humanoid's 1394 control system on the
//! simulated bus, its timing analysis and the CAN comparison.
//!
//! - [`config`]: the robot (modules on the card's chains, their
//!   parameters and physics, the computer, the period, the gait);
//!   `configs/mahru-seed002.json`.
//! - [`rig`]: the bus: the computer's 3-port card at the root, one chain
//!   per port, and the computer's port with its real-time system's
//!   overhead.
//! - [`gait`]: a walking-like trajectory for the ten joints.
//! - [`main_loop`]: the MainController's period (read all, compute,
//!   QWRITE) with the seed's computation and slack.
//! - [`demo`]: `firelink demo --robot mahru`.
//! - [`budget`]: Table I from simulated transaction times, the seed's
//!   example, and the same budget measured end to end.
//! - [`table3`]: read-transaction time by payload under both real-time
//!   systems (Table III).
//! - [`can`]: the same 14-module cycle on a CAN bus (Table IV).
//! - [`tables`]: `firelink budget`: Tables I, III and IV in one run.

pub mod budget;
pub mod can;
pub mod config;
pub mod demo;
pub mod gait;
pub mod main_loop;
pub mod rig;
pub mod table3;
pub mod tables;

pub use config::MahruConfig;
pub use demo::{MahruDemoOptions, MahruDemoReport, run_mahru_demo};
