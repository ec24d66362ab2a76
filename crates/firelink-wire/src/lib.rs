//! # firelink-wire: the bytes on the wire, and nothing else
//!
//! The bottom layer of Firelink. Pure codecs with no I/O, no clock and no
//! allocation: everything above (the simulated bus, the emulated boards, the
//! host library) speaks through these types.
//!
//! - [`crc`]: the IEEE 1394 CRC-32 (header and data CRC).
//! - [`packet`]: asynchronous packets: tcodes, acks, rcodes, a checked
//!   zero-copy [`Packet`](packet::Packet) view and the
//!   [`PacketRepr`](packet::PacketRepr) meaning type.
//! - [`phy`]: PHY packets (self-ID, PHY configuration, link-on).
//! - [`bridge`]: the Ethernet/UDP bridge framing (control word, extra data).
//! - [`fw_cdev`]: Linux firewire-cdev ioctl arguments and events, and the
//!   /dev/fw* twin's request/reply framing.
//! - [`qla`]: the QLA family's board protocol (FPGA1394 + QLA1 or DQLA):
//!   address spaces and the
//!   register map, register quadlet codecs, the real-time read and write
//!   blocks, and the broadcast protocol (query, status broadcasts, hub
//!   block, command block).
//! - [`snake`]: seed 001's 7-channel Snake robot node: its address map
//!   (Table 1), registers (Table 2 and the channel devices) and its
//!   fixed-size real-time blocks with valid bits (Fig. 17).

//! - [`mahru`]: the MAHRU humanoid's module protocol of seed 002 (command
//!   codes in the destination offset, module IDs, joint, force/torque,
//!   set-point and parameter blocks).
//!
//! Every parser checks lengths before reading; untrusted bytes never panic
//! and failures are [`Error`] values naming what was wrong.
//!
//! ```
//! use firelink_wire::packet::{Packet, PacketRepr};
//! // A quadlet read request header from the test vectors, with its CRC.
//! let bytes = [0xff, 0xc1, 0x15, 0x40, 0xff, 0xc2, 0x00, 0x00,
//!              0x00, 0x00, 0x00, 0x07, 0xb2, 0xb0, 0x28, 0x23];
//! let packet = Packet::new_checked(&bytes[..]).unwrap();
//! assert_eq!(packet.tl(), 5);
//! assert_eq!(packet.offset(), 7);
//! assert_eq!(packet.header_crc_ok(), Some(true));
//! let repr = PacketRepr::parse(&packet).unwrap();
//! assert_eq!(repr.tcode().name(), "read_request_quadlet");
//! ```
#![no_std]
#![cfg_attr(not(test), warn(clippy::indexing_slicing))]

#[cfg(test)]
extern crate std;

pub mod bridge;
pub mod crc;
mod error;
pub mod field;
pub mod fw_cdev;
pub mod human;
pub mod mahru;
mod open_enum;
pub mod packet;
pub mod pcap;
pub mod phy;
pub mod qla;
pub mod snake;

pub use error::{Error, Result};
