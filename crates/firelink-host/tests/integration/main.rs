//! The integration tests of `firelink-host`, built as one test binary: one
//! link for the crate instead of one per file, and libtest runs the tests
//! of every file on the same threads. Each file of this folder is a module
//! declared below (a test's name is `file::test`); a new test file joins
//! with one `mod` line. See ARCHITECTURE.md, "Tests".

mod replay;
#[cfg(feature = "sim")]
mod rev9_v3;
#[cfg(feature = "sim")]
mod sim_groups;
#[cfg(feature = "sim")]
mod sim_io;
#[cfg(feature = "sim")]
mod snake;
#[cfg(feature = "sim")]
mod steady_cycle_allocations;
mod udp_port;
#[cfg(feature = "sim")]
mod wrappers;
