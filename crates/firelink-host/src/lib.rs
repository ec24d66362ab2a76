//! # firelink-host: what a robot program links against
//!
//! The PC side of the seed papers: ports that carry 1394 transactions (the
//! in-process simulated bus, or UDP to an Ethernet-bridge board), discovery
//! of boards, a typed board API, and the I/O protocols that move one servo
//! cycle's inputs and outputs: sequential per-board read/write, sequential
//! read with a broadcast write, and seed 000's broadcast query / hub read /
//! broadcast command protocol.
//!
//! - [`port`]: the one narrow [`Port`] trait, and the link filters wrappers use.
//! - [`transaction`]: labels, generation and response matching, once for
//!   every link.
//! - [`udp`]: the Ethernet bridge port.
//! - `sim`: the simulated-bus port (cargo feature `sim`, on by default).
//! - `firewire`: a PC's FireWire card through Linux firewire-cdev
//!   (cargo feature `firewire`, on by default; Linux only).
//! - [`trace`] and [`fault`]: port wrappers that record every call and
//!   packet (pcap of any port), and that lose and damage packets;
//!   [`replay`]: a port answering from such a recording.
//! - [`qla`]: the QLA family's wing (the dVRK's boards): [`qla::scan`],
//!   discovery and protocol choice; [`qla::board`], the per-board I/O
//!   buffers and accessors; [`qla::io`], the I/O system running the three
//!   protocols; [`qla::extras`], the firmware features beyond the servo
//!   cycle (PROMs and serial numbers, digital outputs and waveforms,
//!   instrument memory, I/O expander, Ethernet registers, motor supply,
//!   PHY registers); the bus tools' work on boards
//!   ([`qla::board_access`], registers by name in
//!   [`qla::register_address`]), the live view of every board
//!   ([`qla::monitor`], [`qla::monitor_frame`]) and the tour of one
//!   broadcast cycle ([`qla::tour`]).
//! - [`cycle_report`]: what every robot's I/O cycle reports
//!   ([`cycle_report::CycleReport`]) and counts
//!   ([`cycle_report::IoStats`]).
//! - [`robot_io`]: seed 001's abstract robot I/O ([`RobotIo`]): latch all
//!   inputs, per-axis get/set, apply all outputs, the same for every
//!   kind of board (implemented for [`qla::io::IoSystem`] and
//!   [`snake::SnakeSystem`]).
//! - [`cpu_latency`]: holding the CPUs awake (a PM QoS request) so that
//!   hand-overs between processes do not wait for a sleeping CPU.
//! - [`stop`]: stop requests (signals, a caller) that end a robot loop
//!   with the robot powered down.
//! - [`snake`]: seed 001's Snake robot nodes: the node layer over block
//!   buffers with valid bits, and every Get/Set of the seed's API.
//! - [`mahru`]: seed 002's MotionController for the MAHRU humanoid's
//!   modules, and its computer's real-time systems as overhead models.
//!
//! Protocols never know which port they use, so the same program drives
//! emulated boards today and real boards over Ethernet tomorrow.

pub mod cpu_latency;
pub mod cycle_report;
pub mod error;
pub mod eth;
pub mod fault;
#[cfg(all(feature = "firewire", target_os = "linux"))]
pub mod firewire;
pub mod hex;
pub mod link_stats;
pub mod mahru;
pub mod pacing;
pub mod packet_json;
pub mod port;
pub mod qla;
pub mod replay;
pub mod robot_io;
#[cfg(feature = "sim")]
pub mod sim;
pub mod snake;
pub mod stop;
pub mod trace;
pub mod transaction;
pub mod udp;

pub use error::{HostError, MissReason, Result};
pub use firelink_wire::qla::registers::WatchdogSetting;
pub use port::{Dest, LinkFilter, Port};
pub use robot_io::{BoardStatus, PowerDown, RobotIo};
