//! # firelink-bus: a simulated IEEE 1394a bus in virtual time
//!
//! A deterministic, discrete-event model of a 1394a cable bus, accurate
//! enough to reproduce the seed papers' wire-time measurements: topology and
//! bus reset with self-ID, PHY registers and the gap count, arbitration
//! (fair, priority and isochronous-style requests and their gaps), packet
//! transmission time from the exact packet length at S100/S200/S400, acks,
//! concatenated versus split responses, an optional cycle master, seeded
//! fault injection, a trace with a text timeline and pcap export.
//!
//! - [`time`]: [`SimTime`] and [`SimDuration`] (picoseconds).
//! - [`timing`]: every timing figure ([`BusTiming`]).
//! - [`node`]: the [`Node`] trait every device implements, and [`NodeCtx`].
//! - [`bus`]: the [`Bus`] itself.
//! - [`topology`]: cables, trees and self-ID numbering.
//! - [`phy`]: PHY registers and PHY packets.
//! - [`fault`]: fault plans, the injector and the fault log.
//! - [`trace`] and [`pcap`]: what happened, as records, text and pcap.
//! - [`ethernet`]: the timing model of the Ethernet-only network of FPGA
//!   V3 boards at firmware Rev 9 (a chain of 1 Gb/s switches, learning,
//!   the broadcast read's hub updates).
//! - [`host`]: the PC's link ([`HostLink`]) and the PC software overhead
//!   model ([`HostModel`]).
//!
//! The nodes on it live in the crates above: emulated boards
//! (`firelink-board`), the host library's port (`firelink-host`'s
//! `SimPort`), the one-cycle simulation behind `firelink sim`
//! (`firelink-testbed`).
//!
//! Nothing here reads a clock or an unseeded RNG: the same nodes, topology,
//! configuration and seed give the same trace, bit for bit.
//!
//! ```
//! use firelink_bus::{Bus, BusConfig, HostLink, NodeConfig, SimDuration};
//! let mut bus = Bus::new(BusConfig::default());
//! let pc = bus.add(HostLink::new("pc"), NodeConfig::pc());
//! let other = bus.add(HostLink::new("other"), NodeConfig::board());
//! bus.daisy_chain(&[pc, other]).unwrap();
//! bus.reset();
//! bus.run_for(SimDuration::from_micros(100));
//! // Self-ID numbers the PC, the root, last.
//! assert_eq!(bus.phy_id(pc), Some(1));
//! ```

pub mod bus;
mod error;
pub mod ethernet;
pub mod fault;
pub mod host;
mod id;
pub mod node;
pub mod pcap;
pub mod phy;
pub mod time;
pub mod timing;
pub mod topology;
pub mod trace;

pub use bus::{Bus, BusConfig, Detail, DetailReport, NodeConfig, PacketLevelWhy, TraceLevel};
pub use error::BusError;
pub use fault::{FaultPlan, FaultRule, PacketFault, PacketMatch, TimedFault};
pub use host::{HostLink, HostModel, Transfer};
pub use node::{ArbitrationClass, Node, NodeCtx, NodeHandle, ResetInfo, RxReply, TransmitRequest};
pub use time::{SimDuration, SimTime};
pub use timing::BusTiming;
