//! The QLA family's wing: what only FPGA1394 boards serve. FPGA V3 boards
//! at firmware Rev 9 on the Ethernet-only network ([`eth_network`]: the
//! boards and the chain in virtual time, no sockets; [`eth_serve`]: the
//! network served over real UDP, `firelink emulate --network eth`) hold
//! no other robot's nodes.
//!
//! The Ethernet bridge (the crate's root) and the /dev/fw* twin
//! (`fw_cdev`) carry any node of the simulated bus, the Snake system's and
//! MAHRU's included, so they stay at the crate's root.

pub mod eth_network;
pub mod eth_serve;
