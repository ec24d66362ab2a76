//! The integration tests of `firelink-cli`, built as one test binary: one
//! link for the crate instead of one per file, and libtest runs the tests
//! of every file on the same threads. Each file of this folder is a module
//! declared below (a test's name is `file::test`); a new test file joins
//! with one `mod` line. See ARCHITECTURE.md, "Tests".

mod cli_args;
mod closed_pipes;
mod common;
mod demo_bench;
mod emulate_cli;
mod fw_port;
mod fw_run_cli;
mod libraw1394;
mod mahru_cli;
mod messages_cli;
mod packet_cli;
mod safe_exits;
mod sim_cli;
mod sim_phases;
mod snake_cli;
mod wireshark;
