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
//! - [`host`]: the PC's link ([`HostLink`]) and the PC software overhead
//!   model ([`HostModel`]).
//! - [`scenario`]: a minimal board responder and the one-cycle simulation
//!   behind `firelink sim`.
//!
//! Nothing here reads a clock or an unseeded RNG: the same nodes, topology,
//! configuration and seed give the same trace, bit for bit.
//!
//! ```
//! use firelink_bus::scenario::{simulate_cycle, CycleConfig, Profile, Protocol};
//! let report = simulate_cycle(&CycleConfig::new(8, Profile::Seed, Protocol::Broadcast));
//! // The command broadcast of seed 000 takes about 3.26 us at S400.
//! let command = report.phase_us("command").unwrap();
//! assert!((command - 3.26).abs() / 3.26 < 0.10);
//! ```

pub mod bus;
mod error;
pub mod fault;
pub mod host;
pub mod node;
pub mod pcap;
pub mod phy;
pub mod scenario;
pub mod time;
pub mod timing;
pub mod topology;
pub mod trace;

pub use bus::{Bus, BusConfig, NodeConfig, NodeHandle, TraceLevel};
pub use error::BusError;
pub use fault::{FaultPlan, FaultRule, PacketFault, PacketMatch, TimedFault};
pub use host::{HostLink, HostModel, Transfer};
pub use node::{ArbitrationClass, Node, NodeCtx, ResetInfo, RxReply, TransmitRequest};
pub use time::{SimDuration, SimTime};
pub use timing::BusTiming;
