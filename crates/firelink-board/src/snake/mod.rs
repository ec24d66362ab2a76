//! Seed 001's Snake robot node: a 7-channel FPGA/1394 board of its own,
//! beside the QLA, with a plant behind every channel.
//!
//! The wire formats are [`firelink_wire::snake`]; this module gives them
//! behaviour:
//! - [`channel`]: one channel's analog side (bridge amplifier in torque
//!   or speed mode, current limit, feedback gain of eq. 1), its digital
//!   potentiometer (wiper, outputs, EEPROM, write protection) and its
//!   encoder counter;
//! - [`config`]: what a node is ([`SnakeNodeConfig`]);
//! - [`firmware`]: the FPGA as a state machine fed raw packets
//!   ([`SnakeFirmware`]);
//! - [`node`]: the firmware on the simulated bus ([`SnakeNode`]).
//!
//! The plants are the existing axis models ([`crate::plant`]): the
//! channel's amplifier decides, every sub-step in speed mode, the current
//! the axis model then drives.
//!
//! ```
//! use firelink_board::qla::{PhyRegisters, Reply};
//! use firelink_board::snake::{SnakeFirmware, SnakeNodeConfig};
//! use firelink_board::time::SimTime;
//! use firelink_wire::packet::{Ack, AsyncHeader, NodeId, Packet, PacketRepr};
//!
//! let mut node = SnakeFirmware::new(SnakeNodeConfig::new(3));
//! let mut phy = PhyRegisters::new(0);
//! node.bus_reset(SimTime::ZERO, 0, 1);
//! // The host (node 1) enables channel 2's amplifier: mask 0x02, enable 0x02.
//! let write = PacketRepr::WriteQuadletRequest {
//!     header: AsyncHeader::new(NodeId::local(0), NodeId::local(1), 0),
//!     offset: 0,
//!     data: 0x0202,
//! };
//! let mut buf = [0u8; 20];
//! write.emit(&mut buf).unwrap();
//! assert_eq!(node.receive(SimTime::from_micros(5), &buf, &mut phy), Reply::Ack(Ack::Complete));
//! // STATUS: board ID 3, channel 2 enabled, mask 0x02 (Table 2).
//! assert_eq!(node.status().raw(), 0x0300_0202);
//! ```

pub mod channel;
pub mod config;
pub mod firmware;
pub mod node;

pub use channel::{AmplifierModel, DigitalPot};
pub use config::{SNAKE_VERSION, SnakeNodeConfig};
pub use firmware::{SnakeFirmware, SnakeNodeStats};
pub use node::SnakeNode;
