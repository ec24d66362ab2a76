//! The integration tests of `firelink-control`, built as one test binary: one
//! link for the crate instead of one per file, and libtest runs the tests
//! of every file on the same threads. Each file of this folder is a module
//! declared below (a test's name is `file::test`); a new test file joins
//! with one `mod` line. See ARCHITECTURE.md, "Tests".

mod alloc_free;
mod common;
mod configs;
mod console_schema;
mod pot_check;
mod runner;
mod runner_alloc;
