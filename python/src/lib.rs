//! `firelink._firelink`: the native half of the Python package `firelink`.
//!
//! Thin bindings over the Rust library, one module per part of the
//! package: `ports` (ports and discovery, [`firelink_host`]), `io_system`
//! (the I/O system with per-axis data as numpy arrays, register access),
//! `snake` (seed 001's Snake nodes), `config`
//! ([`firelink_control::config`]), `runs` (the demo and the benchmark),
//! `emulator` (the in-process emulator, [`firelink_testbed`]) and
//! `packets` (packet records, [`firelink_host::packet_json`]). Every call
//! that does I/O or simulation releases the GIL; every error becomes one of
//! the package's exceptions (defined in `firelink/_errors.py`, raised from
//! `errors`) with the library's one-line message. Bad input raises; it
//! never panics: every argument is converted with its name and range first
//! (`args`), and long calls return on Ctrl-C (`interrupt`).

mod args;
mod config;
mod emulator;
mod errors;
mod interrupt;
mod io_system;
mod packets;
mod ports;
mod runs;
mod snake;

use std::sync::{Mutex, PoisonError};

use pyo3::prelude::*;

use firelink_host::Port as HostPort;

use config::{Config, load_config, parse_config};
use emulator::Emulator;
use io_system::IoSystem;
use packets::{crc1394, decode_packet_json, encode_packet_json};
use ports::{Board, Port, parse_port};
use runs::{run_bench_json, run_demo_json};

/// Any port, movable between threads (the GIL is released around I/O).
pub(crate) type AnyPort = Box<dyn HostPort + Send>;

/// The value behind a mutex that `&mut` access makes exclusive anyway (no
/// locking; a poisoned mutex still holds a usable value).
pub(crate) fn exclusive<T>(m: &mut Mutex<T>) -> &mut T {
    m.get_mut().unwrap_or_else(PoisonError::into_inner)
}

/// The native module.
#[pymodule]
fn _firelink(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Port>()?;
    m.add_class::<Board>()?;
    m.add_class::<IoSystem>()?;
    m.add_class::<Emulator>()?;
    m.add_class::<Config>()?;
    snake::register(m)?;
    m.add_function(wrap_pyfunction!(load_config, m)?)?;
    m.add_function(wrap_pyfunction!(parse_port, m)?)?;
    m.add_function(wrap_pyfunction!(parse_config, m)?)?;
    m.add_function(wrap_pyfunction!(run_demo_json, m)?)?;
    m.add_function(wrap_pyfunction!(run_bench_json, m)?)?;
    m.add_function(wrap_pyfunction!(decode_packet_json, m)?)?;
    m.add_function(wrap_pyfunction!(encode_packet_json, m)?)?;
    m.add_function(wrap_pyfunction!(crc1394, m)?)?;
    Ok(())
}
