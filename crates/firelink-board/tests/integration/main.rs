//! The integration tests of `firelink-board`, built as one test binary: one
//! link for the crate instead of one per file, and libtest runs the tests
//! of every file on the same threads. Each file of this folder is a module
//! declared below (a test's name is `file::test`); a new test file joins
//! with one `mod` line. See ARCHITECTURE.md, "Tests".

mod broadcast;
mod bus;
mod common;
mod motion;
mod plant_accuracy;
mod registers;
mod snake;
