//! The integration tests of `firelink-testbed`, built as one test binary: one
//! link for the crate instead of one per file, and libtest runs the tests
//! of every file on the same threads. Each file of this folder is a module
//! declared below (a test's name is `file::test`); a new test file joins
//! with one `mod` line. See ARCHITECTURE.md, "Tests".

mod bench_udp;
mod console_homing;
mod demo;
mod detail_levels;
mod fault_script;
mod mahru;
mod mahru_config;
mod rescan;
mod safe_exits;
mod service;
mod sim_faults;
mod sim_validation;
mod snake;
mod soak;
mod stops;
mod teleop;
