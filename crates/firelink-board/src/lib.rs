//! # firelink-board: the emulated boards of the three seed systems
//!
//! Software boards with a deterministic physical plant behind them: the
//! dVRK's FPGA1394 (V2, V3) + QLA1/DQLA, which behave on the wire like the
//! public firmware at revisions 7, 8 and 9 and like the seed-000 era
//! broadcast firmware; seed 001's Snake node; seed 002's MAHRU modules.
//! Facts: `shared/spec/fpga-board.md` (registers, blocks, broadcast,
//! watchdog and safety) and `shared/spec/ieee1394.md` (packets, acks).
//!
//! Layers, bottom up:
//! - [`time`]: virtual time in picoseconds and the 49.152 MHz FPGA clock.
//! - [`plant`]: per axis a current amplifier, a DC motor with friction,
//!   gear train and load, a quadrature encoder with edge timing, a
//!   potentiometer, current sense with seeded noise and the amplifier
//!   temperature; dVRK presets.
//! - [`qla`]: the QLA family's firmware (FPGA1394 + QLA1 or DQLA), the
//!   board as a bus-agnostic state machine fed raw packets: link rules,
//!   registers, real-time blocks, broadcast/hub, watchdog and safety. Bit
//!   packing comes from
//!   [`firelink_wire::qla`].
//!   With it: [`qla::config`], what a board is (board ID, QLA1/DQLA,
//!   firmware profile, FPGA version, axes, seed); [`qla::node`],
//!   [`BoardNode`](qla::node::BoardNode), the firmware as a
//!   [`firelink_bus::Node`] on the simulated bus; [`qla::rig`], ready-made
//!   buses of such boards.
//! - [`snake`]: seed 001's 7-channel Snake robot node, a board model of
//!   its own beside the QLA (firmware, channels, bus node).
//! - [`mahru`]: seed 002's MAHRU humanoid modules (DSP + FPGA motor
//!   controllers and force/torque sensors) as bus nodes speaking the
//!   module protocol of [`firelink_wire::mahru`].
//!
//! Everything takes `now`; nothing reads a clock. The same configuration,
//! seed and packet sequence give the same run, bit for bit.
//!
//! ```
//! use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
//! use firelink_board::qla::{Firmware, PhyRegisters, Reply};
//! use firelink_board::time::SimTime;
//! use firelink_wire::packet::{Ack, AsyncHeader, NodeId, PacketRepr};
//!
//! let mut board = Firmware::new(BoardConfig::new(0, Hardware::Qla1, Profile::Rev8));
//! let mut phy = PhyRegisters::new(0);
//! board.bus_reset(SimTime::ZERO, 0, 1);
//! // The host (node 1) switches motor power on: a unified quadlet write.
//! let write = PacketRepr::WriteQuadletRequest {
//!     header: AsyncHeader::new(NodeId::local(0), NodeId::local(1), 0),
//!     offset: 0,
//!     data: 0x000C_0000,
//! };
//! let mut buf = [0u8; 20];
//! let len = write.emit(&mut buf).unwrap();
//! let reply = board.receive(SimTime::from_micros(5), &buf[..len], &mut phy);
//! assert_eq!(reply, Reply::Ack(Ack::Complete));
//! // 10 ms later the motor supply is good (STATUS bit 19).
//! assert_ne!(board.read_quadlet(SimTime::from_millis(10), 0) & (1 << 19), 0);
//! ```
#![cfg_attr(not(test), warn(clippy::indexing_slicing))]

pub mod mahru;
pub mod plant;
pub mod qla;
pub mod snake;
pub mod time;
