//! # firelink-host: what a robot program links against
//!
//! The PC side of the seed papers: ports that carry 1394 transactions (the
//! in-process simulated bus, or UDP to an Ethernet-bridge board), discovery
//! of boards, a typed board API, and the I/O protocols that move one servo
//! cycle's inputs and outputs: sequential per-board read/write, sequential
//! read with a broadcast write, and seed 000's broadcast query / hub read /
//! broadcast command protocol.
//!
//! - [`port`]: the one narrow [`Port`](port::Port) trait.
//! - [`transaction`]: labels, generation and response matching, once for
//!   every link.
//! - [`udp`]: the Ethernet bridge port.
//! - [`sim`]: the simulated-bus port.
//! - [`scan`]: discovery and protocol choice.
//! - [`board`]: the per-board I/O buffers and accessors.
//! - [`io`]: the I/O system running the three protocols.
//! - [`mahru`]: seed 002's MotionController for the MAHRU humanoid's
//!   modules, and its computer's real-time systems as overhead models.
//!
//! Protocols never know which port they use, so the same program drives
//! emulated boards today and real boards over Ethernet tomorrow.

pub mod board;
pub mod error;
pub mod io;
pub mod mahru;
pub mod pacing;
pub mod packet_json;
pub mod port;
pub mod scan;
pub mod sim;
pub mod transaction;
pub mod udp;

pub use error::{HostError, MissReason, Result};
pub use port::{Dest, Port};
