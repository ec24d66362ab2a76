//! The integration tests of `firelink-ros2`, built as one test binary: each
//! file of this folder is a module declared below (a test's name is
//! `file::test`); a new test file joins with one `mod` line. See
//! ARCHITECTURE.md, "Tests". (The DDS tests, which need a network
//! namespace, are `tests/dds/*.py`, run by `scripts/test-ros2`.)

mod period;
mod servo_stream;
