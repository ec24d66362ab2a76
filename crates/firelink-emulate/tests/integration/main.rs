//! The integration tests of `firelink-emulate`, built as one test binary: one
//! link for the crate instead of one per file, and libtest runs the tests
//! of every file on the same threads. Each file of this folder is a module
//! declared below (a test's name is `file::test`); a new test file joins
//! with one `mod` line. See ARCHITECTURE.md, "Tests".

mod bridge_multicast;
mod broadcast_cycles;
mod common;
mod detail_levels;
mod eth_common;
mod eth_host;
mod eth_mixed;
mod eth_network;
mod eth_udp;
mod flood;
mod fw_cdev_faults;
mod fw_cdev_protocol;
mod host_extras;
mod reference_sequences;
mod register_exact;
mod rev9_boards;
mod seq_read_broadcast_write;
mod udp_io;
