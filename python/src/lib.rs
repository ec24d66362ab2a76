//! `firelink._firelink`: the native half of the Python package `firelink`.
//!
//! Thin bindings over the Rust library: ports and discovery
//! ([`firelink_host`]), the I/O system with per-axis data as numpy arrays,
//! register access, seed 001's Snake nodes ([`snake`]), configurations ([`firelink_control::config`]), the demo,
//! the benchmark and the in-process emulator ([`firelink_testbed`]), packet
//! records ([`firelink_host::packet_json`]). Every call that does I/O or
//! simulation releases the GIL; every error becomes one of the package's
//! exceptions (defined in `firelink/_errors.py`) with the library's
//! one-line message. Bad input raises; it never panics.

mod snake;

use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant};

use numpy::{IntoPyArray, PyArray1, PyReadonlyArray1};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

use firelink_board::config::Profile;
use firelink_control::config::{ConfigErrors, IoConfig, presets};
use firelink_control::runner::Pacing;
use firelink_host::io::{IoOptions, IoSystem as HostIoSystem};
use firelink_host::packet_json::{self, PacketJson};
use firelink_host::port::Dest;
use firelink_host::scan::Protocol;
use firelink_host::udp::{UdpPort, WaitMode};
use firelink_host::{HostError, Port as HostPort, WatchdogSetting};
use firelink_testbed::TestbedError;
use firelink_testbed::bench::{BenchOptions, BenchTransport};
use firelink_testbed::demo::{DemoFault, DemoOptions, DemoPort};
use firelink_testbed::rig;

/// Any port, movable between threads (the GIL is released around I/O).
type AnyPort = Box<dyn HostPort + Send>;

/// The value behind a mutex that `&mut` access makes exclusive anyway (no
/// locking; a poisoned mutex still holds a usable value).
fn exclusive<T>(m: &mut Mutex<T>) -> &mut T {
    m.get_mut().unwrap_or_else(PoisonError::into_inner)
}

// ------------------------------------------------------------ errors ---

/// An exception of the package's own hierarchy (`firelink._errors`).
fn error<'py>(py: Python<'py>, class: &str, args: impl IntoPyObject<'py>) -> PyErr {
    let made = py
        .import("firelink._errors")
        .and_then(|m| m.getattr(class))
        .and_then(|c| c.call1((args,)));
    match made {
        Ok(instance) => PyErr::from_value(instance),
        Err(e) => e,
    }
}

fn host_error(py: Python<'_>, e: HostError) -> PyErr {
    let class = match e {
        HostError::Timeout { .. } => "BusTimeout",
        HostError::NoBoards { .. } => "NoBoardsError",
        HostError::InvalidRequest { .. } | HostError::UnknownBoard(_) => "InvalidRequest",
        _ => "BusError",
    };
    error(py, class, e.to_string())
}

fn testbed_error(py: Python<'_>, e: TestbedError) -> PyErr {
    match e {
        TestbedError::Host(h) => host_error(py, h),
        TestbedError::Config(text) => error(py, "FirelinkError", text),
        other => error(py, "FirelinkError", other.to_string()),
    }
}

fn config_error(py: Python<'_>, e: &ConfigErrors) -> PyErr {
    let first = e.first();
    let made = py
        .import("firelink._errors")
        .and_then(|m| m.getattr("ConfigError"))
        .and_then(|c| {
            c.call1((
                e.to_string(),
                first.file.clone(),
                first.path.clone(),
                first.problem.to_string(),
            ))
        });
    match made {
        Ok(instance) => PyErr::from_value(instance),
        Err(err) => err,
    }
}

fn bad(py: Python<'_>, text: impl Into<String>) -> PyErr {
    error(py, "InvalidRequest", text.into())
}

/// Issue a Python `UserWarning` (e.g. the watchdog is off).
pub(crate) fn warn(py: Python<'_>, text: &str) -> PyResult<()> {
    let category = py.get_type::<pyo3::exceptions::PyUserWarning>();
    let text = std::ffi::CString::new(text).unwrap_or_default();
    PyErr::warn(py, &category, &text, 1)
}

/// A watchdog argument: a period in ms (int or float) or the string
/// `"off"`; the one rule is `WatchdogSetting` (one tick to 65535 ticks).
pub(crate) fn watchdog_setting(
    py: Python<'_>,
    value: &Bound<'_, PyAny>,
) -> PyResult<WatchdogSetting> {
    if let Ok(text) = value.extract::<String>() {
        return WatchdogSetting::parse(&text)
            .map_err(|e| bad(py, format!("watchdog {text:?}: {e}")));
    }
    if value.is_instance_of::<pyo3::types::PyBool>() {
        return Err(bad(py, "watchdog: a period in ms or \"off\", not a bool"));
    }
    match value.extract::<f64>() {
        Ok(ms) => WatchdogSetting::from_ms(ms).map_err(|e| bad(py, e.to_string())),
        Err(_) => Err(bad(
            py,
            format!(
                "watchdog: a period in ms or \"off\", not {}",
                value
                    .get_type()
                    .name()
                    .map_or_else(|_| "this".to_string(), |n| n.to_string())
            ),
        )),
    }
}

// ------------------------------------------------------------- ports ---

fn profile(py: Python<'_>, name: &str) -> PyResult<Profile> {
    match name {
        "7" | "rev7" => Ok(Profile::Rev7),
        "8" | "rev8" => Ok(Profile::Rev8),
        "seed" => Ok(Profile::Seed),
        _ => Err(error(
            py,
            "PortError",
            format!("unknown firmware {name:?}: expected 7, 8 or seed"),
        )),
    }
}

/// Open a `udp:HOST[:PORT]` port.
fn open_udp(py: Python<'_>, spec: &str) -> PyResult<(AnyPort, String)> {
    let addr = UdpPort::parse_address(spec).map_err(|e| error(py, "PortError", e.to_string()))?;
    let port = rig::udp_port(addr).map_err(|e| testbed_error(py, e))?;
    Ok((Box::new(port), format!("udp:{addr}")))
}

/// Open a port from its description (see `firelink.open`).
fn open_port(py: Python<'_>, spec: &str) -> PyResult<(AnyPort, String)> {
    let spec = spec.trim();
    let dvrk = presets::dvrk_seed000();
    if spec.starts_with("udp") {
        return open_udp(py, spec);
    }
    let mut parts = spec.split(':');
    if parts.next() != Some("sim") {
        return Err(error(
            py,
            "PortError",
            format!("unknown port {spec:?}: sim[:BOARDS[:FIRMWARE]] or udp:HOST[:PORT]"),
        ));
    }
    let boards = match parts.next() {
        None => 8,
        Some(n) => n
            .parse::<usize>()
            .ok()
            .filter(|n| (1..=16).contains(n))
            .ok_or_else(|| {
                error(
                    py,
                    "PortError",
                    format!("port {spec:?}: the board count is 1..=16, not {n:?}"),
                )
            })?,
    };
    let firmware = profile(py, parts.next().unwrap_or("8"))?;
    if let Some(extra) = parts.next() {
        return Err(error(
            py,
            "PortError",
            format!("port {spec:?}: unexpected {extra:?} after the firmware"),
        ));
    }
    let configs = rig::board_configs(&dvrk, firmware, boards);
    let (port, _) = rig::sim_port(configs, false).map_err(|e| testbed_error(py, e))?;
    Ok((Box::new(port), spec.to_string()))
}

fn node(py: Python<'_>, node: u32) -> PyResult<Dest> {
    if node > 63 {
        return Err(bad(
            py,
            format!("node {node}: node IDs are 0..=63 (63: broadcast)"),
        ));
    }
    Ok(Dest::node(node as u8))
}

fn offset(py: Python<'_>, address: u64) -> PyResult<u64> {
    if address > firelink_wire::packet::MAX_OFFSET {
        return Err(bad(py, format!("address {address:#x} is beyond 48 bits")));
    }
    Ok(address)
}

/// A board found by a scan.
#[pyclass(frozen, get_all, module = "firelink._firelink")]
#[derive(Clone)]
struct Board {
    /// Board ID from the rotary switch, 0..=15.
    board_id: u8,
    /// Physical node ID in the current bus generation.
    node: u8,
    /// FW_VERSION.
    firmware: u32,
    /// Companion board: "QLA1", "DQLA", "dRA1" or "unknown".
    hardware: String,
    /// FPGA board version, e.g. "V2".
    fpga: String,
    /// Motor axes.
    axes: usize,
}

#[pymethods]
impl Board {
    fn __repr__(&self) -> String {
        format!(
            "Board(board_id={}, node={}, firmware={}, hardware={:?}, fpga={:?}, axes={})",
            self.board_id, self.node, self.firmware, self.hardware, self.fpga, self.axes
        )
    }
}

impl From<&firelink_host::board::BoardInfo> for Board {
    fn from(b: &firelink_host::board::BoardInfo) -> Self {
        Board {
            board_id: b.board_id,
            node: b.node,
            firmware: b.firmware,
            hardware: b.hardware.name().to_string(),
            fpga: format!("{:?}", b.fpga),
            axes: b.layout.motors(),
        }
    }
}

/// A port to the boards: the simulated bus or UDP.
#[pyclass(module = "firelink._firelink")]
struct Port {
    /// The mutex is never contended (PyO3 hands out `&mut self` one at a
    /// time); it makes the class `Sync`, as PyO3 requires.
    inner: Mutex<Option<AnyPort>>,
    name: String,
}

impl Port {
    fn get(&mut self, py: Python<'_>) -> PyResult<&mut AnyPort> {
        let name = &self.name;
        exclusive(&mut self.inner).as_mut().ok_or_else(|| {
            error(
                py,
                "PortError",
                format!("port {name} was handed to an IoSystem and is no longer usable here"),
            )
        })
    }
}

#[pymethods]
impl Port {
    /// Open a port: see `firelink.open`.
    #[new]
    fn new(py: Python<'_>, spec: &str) -> PyResult<Port> {
        let (inner, name) = open_port(py, spec)?;
        Ok(Port {
            inner: Mutex::new(Some(inner)),
            name,
        })
    }

    /// The port's name.
    #[getter]
    fn name(&self) -> String {
        self.name.clone()
    }

    /// Seconds on the port's clock (virtual on the simulated bus).
    #[getter]
    fn now(&mut self, py: Python<'_>) -> PyResult<f64> {
        Ok(self.get(py)?.now().as_secs_f64())
    }

    /// Let `seconds` pass (virtual time on the simulated bus).
    fn wait(&mut self, py: Python<'_>, seconds: f64) -> PyResult<()> {
        let d = duration(py, seconds, "seconds")?;
        let port = self.get(py)?;
        py.detach(|| port.wait(d));
        Ok(())
    }

    /// Discover the boards; a list of `Board`, sorted by board ID.
    fn scan(&mut self, py: Python<'_>) -> PyResult<Vec<Board>> {
        let port = self.get(py)?;
        let report = py
            .detach(|| firelink_host::scan::scan(port))
            .map_err(|e| host_error(py, e))?;
        Ok(report.boards.iter().map(Board::from).collect())
    }

    /// Read one quadlet at `address` of physical node `node`.
    fn read_quadlet(&mut self, py: Python<'_>, node: u32, address: u64) -> PyResult<u32> {
        let (dest, offset) = (self::node(py, node)?, self::offset(py, address)?);
        let port = self.get(py)?;
        py.detach(|| port.read_quadlet(dest, offset))
            .map_err(|e| host_error(py, e))
    }

    /// Write one quadlet (node 63: broadcast).
    fn write_quadlet(
        &mut self,
        py: Python<'_>,
        node: u32,
        address: u64,
        value: u32,
    ) -> PyResult<()> {
        let (dest, offset) = (self::node(py, node)?, self::offset(py, address)?);
        let port = self.get(py)?;
        py.detach(|| port.write_quadlet(dest, offset, value))
            .map_err(|e| host_error(py, e))
    }

    /// Read `quadlets` quadlets (1..=512) from `address`; the bytes.
    fn read_block<'py>(
        &mut self,
        py: Python<'py>,
        node: u32,
        address: u64,
        quadlets: usize,
    ) -> PyResult<Bound<'py, PyBytes>> {
        let (dest, offset) = (self::node(py, node)?, self::offset(py, address)?);
        if !(1..=512).contains(&quadlets) {
            return Err(bad(
                py,
                format!("{quadlets} quadlets: a block read is 1..=512 quadlets"),
            ));
        }
        let port = self.get(py)?;
        let mut out = vec![0u8; quadlets * 4];
        py.detach(|| port.read_block(dest, offset, &mut out))
            .map_err(|e| host_error(py, e))?;
        Ok(PyBytes::new(py, &out))
    }

    /// Write `data` (a whole number of quadlets, at most 2048 bytes).
    fn write_block(
        &mut self,
        py: Python<'_>,
        node: u32,
        address: u64,
        data: &[u8],
    ) -> PyResult<()> {
        let (dest, offset) = (self::node(py, node)?, self::offset(py, address)?);
        if data.is_empty() || data.len() % 4 != 0 || data.len() > 2048 {
            return Err(bad(
                py,
                format!(
                    "{} bytes: a block write is 4..=2048 bytes, whole quadlets",
                    data.len()
                ),
            ));
        }
        let port = self.get(py)?;
        py.detach(|| port.write_block(dest, offset, data))
            .map_err(|e| host_error(py, e))
    }

    fn __repr__(&self) -> String {
        format!("Port({:?})", self.name)
    }
}

/// Take the port out of a `Port` object for a system (`what`) that owns it
/// from now on.
fn take_port(py: Python<'_>, port: &Bound<'_, PyAny>, what: &str) -> PyResult<AnyPort> {
    let Ok(p) = port.cast::<Port>() else {
        return Err(error(
            py,
            "PortError",
            format!("{what}(port): port must be a firelink.Port or a port description string"),
        ));
    };
    let mut p = p.borrow_mut();
    let name = p.name.clone();
    exclusive(&mut p.inner).take().ok_or_else(|| {
        error(
            py,
            "PortError",
            format!("port {name} is already used by an IoSystem or a SnakeSystem"),
        )
    })
}

fn duration(py: Python<'_>, seconds: f64, what: &str) -> PyResult<Duration> {
    if !(seconds.is_finite() && (0.0..=86_400.0).contains(&seconds)) {
        return Err(bad(py, format!("{what} = {seconds}: must be 0..=86400 s")));
    }
    Ok(Duration::from_secs_f64(seconds))
}

// --------------------------------------------------------- I/O system ---

/// The boards' I/O: one cycle reads every board and writes every board.
#[pyclass(module = "firelink._firelink")]
struct IoSystem {
    /// Never contended (see [`Port`]).
    io: Mutex<HostIoSystem<AnyPort>>,
    /// (board index, axis) of every axis, in board order.
    axes: Vec<(usize, usize)>,
}

fn protocol(py: Python<'_>, name: Option<&str>) -> PyResult<Option<Protocol>> {
    name.map(|n| {
        Protocol::from_name(n).ok_or_else(|| {
            bad(
                py,
                format!("unknown protocol {n:?}: sequential, sequential-read-broadcast-write or broadcast"),
            )
        })
    })
    .transpose()
}

impl IoSystem {
    fn board_index(&mut self, py: Python<'_>, board_id: Option<u8>) -> PyResult<Vec<usize>> {
        match board_id {
            None => Ok((0..exclusive(&mut self.io).boards().len()).collect()),
            Some(id) => exclusive(&mut self.io)
                .boards()
                .iter()
                .position(|b| b.board_id() == id)
                .map(|i| vec![i])
                .ok_or_else(|| bad(py, format!("no board {id} in this system"))),
        }
    }

    fn per_axis<T: Copy + Default>(
        &mut self,
        f: impl Fn(&firelink_host::board::BoardIo, usize) -> Option<T>,
    ) -> Vec<T> {
        let boards = exclusive(&mut self.io).boards();
        self.axes
            .iter()
            .map(|&(b, a)| {
                boards
                    .get(b)
                    .and_then(|board| f(board, a))
                    .unwrap_or_default()
            })
            .collect()
    }

    fn check_len(&mut self, py: Python<'_>, n: usize, what: &str) -> PyResult<()> {
        if n != self.axes.len() {
            return Err(bad(
                py,
                format!("{what}: {n} values for {} axes", self.axes.len()),
            ));
        }
        Ok(())
    }
}

#[pymethods]
impl IoSystem {
    /// Take `port` (a `Port` or a port description), scan it and choose the
    /// protocol (the best the boards support, or `protocol`).
    #[new]
    #[pyo3(signature = (port, protocol=None))]
    fn new(py: Python<'_>, port: &Bound<'_, PyAny>, protocol: Option<&str>) -> PyResult<IoSystem> {
        let chosen = self::protocol(py, protocol)?;
        let inner: AnyPort = if let Ok(text) = port.extract::<String>() {
            open_port(py, &text)?.0
        } else {
            take_port(py, port, "IoSystem")?
        };
        let config = IoOptions {
            protocol: chosen,
            ..IoOptions::default()
        };
        let (io, _) = py
            .detach(|| HostIoSystem::open(inner, config))
            .map_err(|e| host_error(py, e))?;
        let axes = io
            .boards()
            .iter()
            .enumerate()
            .flat_map(|(b, board)| (0..board.axes()).map(move |a| (b, a)))
            .collect();
        Ok(IoSystem {
            io: Mutex::new(io),
            axes,
        })
    }

    /// The boards, in board-ID order.
    #[getter]
    fn boards(&mut self) -> Vec<Board> {
        exclusive(&mut self.io)
            .boards()
            .iter()
            .map(|b| Board::from(b.info()))
            .collect()
    }

    /// The protocol in use.
    #[getter]
    fn protocol(&mut self) -> &'static str {
        exclusive(&mut self.io).protocol().name()
    }

    /// Number of axes over all boards.
    #[getter]
    fn axes(&mut self) -> usize {
        self.axes.len()
    }

    /// Seconds on the port's clock.
    #[getter]
    fn now(&mut self) -> f64 {
        exclusive(&mut self.io).port().now().as_secs_f64()
    }

    /// Let `seconds` pass (virtual time on the simulated bus).
    fn wait(&mut self, py: Python<'_>, seconds: f64) -> PyResult<()> {
        let d = duration(py, seconds, "seconds")?;
        let io = exclusive(&mut self.io);
        py.detach(|| io.port_mut().wait(d));
        Ok(())
    }

    /// Read every board; True when every board answered.
    fn read_all(&mut self, py: Python<'_>) -> bool {
        let io = exclusive(&mut self.io);
        py.detach(|| io.read_all().all_ok())
    }

    /// Write every board's commands; True when nothing failed.
    fn write_all(&mut self, py: Python<'_>) -> bool {
        let io = exclusive(&mut self.io);
        py.detach(|| io.write_all().all_ok())
    }

    /// One whole cycle (read, then write); True when nothing failed.
    fn cycle(&mut self, py: Python<'_>) -> bool {
        let io = exclusive(&mut self.io);
        py.detach(|| io.cycle().all_ok())
    }

    /// Run `cycles` read+write cycles in Rust with the GIL released; the
    /// wall time they took, seconds (the baseline of the Python overhead
    /// benchmark).
    fn run_cycles(&mut self, py: Python<'_>, cycles: u64) -> f64 {
        let io = exclusive(&mut self.io);
        py.detach(|| {
            let start = Instant::now();
            for _ in 0..cycles {
                io.read_all();
                io.write_all();
            }
            start.elapsed().as_secs_f64()
        })
    }

    /// Signed encoder counts per axis (int32).
    fn encoder_counts<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray1<i32>> {
        self.per_axis(|b, a| b.encoder_counts(a)).into_pyarray(py)
    }

    /// Encoder velocity per axis, counts/s (float64).
    fn velocity<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.per_axis(|b, a| b.encoder_velocity(a)).into_pyarray(py)
    }

    /// Potentiometer ADC bits per axis (uint16).
    fn pot<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray1<u16>> {
        self.per_axis(|b, a| b.pot_bits(a)).into_pyarray(py)
    }

    /// Measured motor current per axis, amps (float64, QLA scaling).
    fn current<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.per_axis(|b, a| b.current_amps(a)).into_pyarray(py)
    }

    /// Amplifier on, per axis (bool).
    fn amp_enabled<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        self.per_axis(|b, a| Some(b.amp_enabled(a)))
            .into_pyarray(py)
    }

    /// The DAC commands that the next write sends, per axis (uint16).
    fn dac<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray1<u16>> {
        self.per_axis(|b, a| b.dac(a)).into_pyarray(py)
    }

    /// Set every axis's DAC command (bits, 0..=65535) for the next write.
    fn set_dac(&mut self, py: Python<'_>, bits: PyReadonlyArray1<'_, i64>) -> PyResult<()> {
        let bits = bits
            .as_slice()
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        self.check_len(py, bits.len(), "set_dac")?;
        if let Some(v) = bits.iter().find(|v| !(0..=65535).contains(*v)) {
            return Err(bad(
                py,
                format!("set_dac: {v} is not a DAC value (0..=65535)"),
            ));
        }
        for (&(b, a), &v) in self.axes.iter().zip(bits) {
            if let Some(board) = exclusive(&mut self.io).boards_mut().get_mut(b) {
                board.set_dac(a, v as u16).map_err(|e| host_error(py, e))?;
            }
        }
        Ok(())
    }

    /// Set every axis's motor current command, amps, with the QLA's
    /// nominal scaling (bits = (amps + 6.25) * 65536 / 12.5), for the next
    /// write. Values outside +-6.25 A are refused.
    fn set_current(&mut self, py: Python<'_>, amps: PyReadonlyArray1<'_, f64>) -> PyResult<()> {
        let amps = amps
            .as_slice()
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        self.check_len(py, amps.len(), "set_current")?;
        if let Some(v) = amps.iter().find(|v| !(v.is_finite() && v.abs() <= 6.25)) {
            return Err(bad(py, format!("set_current: {v} A is outside +-6.25 A")));
        }
        for (&(b, a), &v) in self.axes.iter().zip(amps) {
            let bits = ((v + 6.25) * 65536.0 / 12.5).round().clamp(0.0, 65535.0) as u16;
            if let Some(board) = exclusive(&mut self.io).boards_mut().get_mut(b) {
                board.set_dac(a, bits).map_err(|e| host_error(py, e))?;
            }
        }
        Ok(())
    }

    /// Request motor power on or off (every board, or `board`) with the next write.
    #[pyo3(signature = (on, board=None))]
    fn set_power(&mut self, py: Python<'_>, on: bool, board: Option<u8>) -> PyResult<()> {
        for i in self.board_index(py, board)? {
            exclusive(&mut self.io).boards_mut()[i].set_power(on);
        }
        Ok(())
    }

    /// Request the safety relay on or off with the next write.
    #[pyo3(signature = (on, board=None))]
    fn set_relay(&mut self, py: Python<'_>, on: bool, board: Option<u8>) -> PyResult<()> {
        for i in self.board_index(py, board)? {
            exclusive(&mut self.io).boards_mut()[i].set_relay(on);
        }
        Ok(())
    }

    /// Request every amplifier (of every board, or `board`) on or off.
    #[pyo3(signature = (on, board=None))]
    fn set_amplifiers(&mut self, py: Python<'_>, on: bool, board: Option<u8>) -> PyResult<()> {
        for i in self.board_index(py, board)? {
            exclusive(&mut self.io).boards_mut()[i].set_all_amps(on);
        }
        Ok(())
    }

    /// Set every board's watchdog: a period in milliseconds (one 5.208 us
    /// tick to 341.33 ms) or `"off"` (a lost host then leaves the
    /// amplifiers on: a warning is issued).
    fn set_watchdog(&mut self, py: Python<'_>, ms: &Bound<'_, PyAny>) -> PyResult<()> {
        let setting = watchdog_setting(py, ms)?;
        if let Some(w) = setting.warning() {
            warn(py, w)?;
        }
        let io = exclusive(&mut self.io);
        py.detach(|| io.set_watchdog(setting))
            .map_err(|e| host_error(py, e))
    }

    /// Power, relay and watchdog state per board, from the last read.
    fn board_status(&mut self) -> Vec<(u8, bool, bool, bool)> {
        exclusive(&mut self.io)
            .boards()
            .iter()
            .map(|b| {
                (
                    b.board_id(),
                    b.power_enabled(),
                    b.relay_on(),
                    b.watchdog_expired(),
                )
            })
            .collect()
    }

    /// Read a register of board `board_id` (quadlet address `offset`).
    fn read_register(&mut self, py: Python<'_>, board_id: u8, offset: u64) -> PyResult<u32> {
        let io = exclusive(&mut self.io);
        py.detach(|| io.read_register(board_id, offset))
            .map_err(|e| host_error(py, e))
    }

    /// Write a register of board `board_id`.
    fn write_register(
        &mut self,
        py: Python<'_>,
        board_id: u8,
        offset: u64,
        value: u32,
    ) -> PyResult<()> {
        let io = exclusive(&mut self.io);
        py.detach(|| io.write_register(board_id, offset, value))
            .map_err(|e| host_error(py, e))
    }

    /// Error counters since the system opened, as a dict.
    fn stats<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        stats_dict(py, exclusive(&mut self.io).stats())
    }

    /// The last cycle: (all boards answered, I/O time in microseconds).
    fn last_cycle(&mut self) -> (bool, f64) {
        cycle_result(exclusive(&mut self.io).report())
    }

    fn __repr__(&mut self) -> String {
        let axes = self.axes.len();
        let io = exclusive(&mut self.io);
        format!(
            "IoSystem(port={:?}, boards={}, axes={axes}, protocol={:?})",
            io.port().name(),
            io.boards().len(),
            io.protocol().name()
        )
    }
}

/// A cycle's report as (nothing failed, I/O time in microseconds).
fn cycle_result(r: &firelink_host::io::CycleReport) -> (bool, f64) {
    (r.all_ok(), r.io_time().as_secs_f64() * 1e6)
}

/// Error counters as a dict (`IoSystem.stats`, `SnakeSystem.stats`).
fn stats_dict<'py>(
    py: Python<'py>,
    s: &firelink_host::io::IoStats,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("cycles", s.cycles)?;
    d.set_item("clean_cycles", s.clean_cycles)?;
    d.set_item("total_errors", s.total_errors())?;
    d.set_item("timeouts", s.timeouts)?;
    d.set_item("bus_resets", s.bus_resets)?;
    d.set_item("bad_packets", s.bad_packets)?;
    d.set_item("nacks", s.nacks)?;
    d.set_item("sequence_errors", s.sequence_errors)?;
    d.set_item("corrupt_queries", s.corrupt_queries)?;
    d.set_item("wrong_board", s.wrong_board)?;
    d.set_item("block_size", s.block_size)?;
    d.set_item("other", s.other)?;
    d.set_item("missed_by_board", s.missed_by_board.to_vec())?;
    Ok(d)
}

// ----------------------------------------------------------- emulator ---

/// An in-process `firelink emulate`: emulated boards behind a UDP bridge
/// on 127.0.0.1. A context manager: `with Emulator(boards=8) as emu:`.
#[pyclass(module = "firelink._firelink")]
struct Emulator {
    inner: Option<rig::Emulator>,
    address: String,
}

#[pymethods]
impl Emulator {
    /// Start `boards` (1..=16) emulated QLA1 boards with `firmware` (7, 8
    /// or seed) for the robots of `config` (default: seed 000's dVRK);
    /// with `robot="snake"`, one Snake node per board of `config`
    /// (default: the six of `configs/snake-seed001.json`) instead, for
    /// `SnakeSystem` (`boards` and `firmware` do not apply).
    #[new]
    #[pyo3(signature = (boards=8, firmware="8", *, robot="qla", config=None))]
    fn new(
        py: Python<'_>,
        boards: usize,
        firmware: &str,
        robot: &str,
        config: Option<&Config>,
    ) -> PyResult<Emulator> {
        let start = match robot {
            "qla" => {
                if !(1..=16).contains(&boards) {
                    return Err(bad(py, format!("{boards} boards: an emulator has 1..=16")));
                }
                let profile = profile(py, firmware)?;
                let dvrk = config.map_or_else(presets::dvrk_seed000, |c| c.inner.clone());
                let configs = rig::board_configs(&dvrk, profile, boards);
                rig::qla_nodes(configs)
            }
            "snake" => {
                let snake = snake::snake_config(config);
                let configs = firelink_testbed::snake::node_configs(&snake, 1)
                    .map_err(|e| testbed_error(py, e))?;
                firelink_testbed::snake::nodes(configs)
            }
            other => {
                return Err(bad(py, format!("unknown robot {other:?}: qla or snake")));
            }
        };
        let emu = py
            .detach(|| rig::Emulator::start_nodes(start))
            .map_err(|e| testbed_error(py, e))?;
        let address = format!("udp:{}", emu.addr);
        Ok(Emulator {
            inner: Some(emu),
            address,
        })
    }

    /// The address to open, e.g. `udp:127.0.0.1:40123`.
    #[getter]
    fn address(&self) -> String {
        self.address.clone()
    }

    /// Whether the emulator still runs.
    #[getter]
    fn running(&self) -> bool {
        self.inner.is_some()
    }

    /// A new port to this emulator. `timeout` (seconds, default 1) is how
    /// long a request waits for its answer: the emulator runs in this
    /// process, so a late answer means the machine stalled the thread, not
    /// that a packet was lost (`firelink.open(emu.address)` keeps the UDP
    /// port's real-time default of 20 ms).
    #[pyo3(signature = (timeout = 1.0))]
    fn port(&self, py: Python<'_>, timeout: f64) -> PyResult<Port> {
        let emu = self
            .inner
            .as_ref()
            .ok_or_else(|| error(py, "EmulatorClosed", "the emulator is stopped".to_string()))?;
        if !(timeout.is_finite() && timeout > 0.0 && timeout <= 60.0) {
            return Err(error(
                py,
                "InvalidRequest",
                format!("timeout {timeout} s: must be above 0 and at most 60"),
            ));
        }
        let mut port = emu.port().map_err(|e| testbed_error(py, e))?;
        port.set_timeout(std::time::Duration::from_secs_f64(timeout));
        Ok(Port {
            inner: Mutex::new(Some(Box::new(port))),
            name: self.address.clone(),
        })
    }

    /// Stop the server thread; its counters as a dict. Stopping twice is
    /// harmless (the second call returns None).
    fn stop<'py>(&mut self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(emu) = self.inner.take() else {
            return Ok(None);
        };
        let stats = py.detach(|| emu.stop()).map_err(|e| testbed_error(py, e))?;
        let d = PyDict::new(py);
        d.set_item("datagrams", stats.datagrams)?;
        d.set_item("replies", stats.replies)?;
        d.set_item("malformed", stats.malformed)?;
        d.set_item("bad_crc", stats.bad_crc)?;
        d.set_item("stale_generation", stats.stale_generation)?;
        d.set_item("summary", stats.to_string())?;
        Ok(Some(d))
    }

    fn __enter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    #[pyo3(signature = (*_args))]
    fn __exit__(
        &mut self,
        py: Python<'_>,
        _args: &Bound<'_, pyo3::types::PyTuple>,
    ) -> PyResult<bool> {
        self.stop(py)?;
        Ok(false)
    }

    fn __repr__(&self) -> String {
        format!(
            "Emulator(address={:?}, running={})",
            self.address,
            self.inner.is_some()
        )
    }
}

// ------------------------------------------------------ configuration ---

/// A validated robot configuration.
#[pyclass(frozen, module = "firelink._firelink")]
struct Config {
    inner: IoConfig,
}

#[pymethods]
impl Config {
    /// Robot names, in file order.
    #[getter]
    fn robots(&self) -> Vec<String> {
        self.inner.robots.iter().map(|r| r.name.clone()).collect()
    }

    /// Number of joints (actuators) over all robots.
    #[getter]
    fn joints(&self) -> usize {
        self.inner.joints().count()
    }

    /// Board IDs used, in first-use order.
    #[getter]
    fn boards(&self) -> Vec<u8> {
        self.inner.boards().iter().map(|b| b.board_id).collect()
    }

    /// The configuration as JSON text (what `load_config` reads back).
    fn to_json(&self) -> String {
        self.inner.to_json_pretty()
    }

    fn __repr__(&self) -> String {
        format!(
            "Config(robots={:?}, joints={})",
            self.robots(),
            self.joints()
        )
    }
}

/// Load and validate a configuration file; raises `ConfigError`.
#[pyfunction]
fn load_config(py: Python<'_>, path: std::path::PathBuf) -> PyResult<Config> {
    IoConfig::load(&path)
        .map(|inner| Config { inner })
        .map_err(|e| config_error(py, &e))
}

/// Parse and validate configuration text; raises `ConfigError`.
#[pyfunction]
#[pyo3(signature = (text, file="<string>"))]
fn parse_config(py: Python<'_>, text: &str, file: &str) -> PyResult<Config> {
    IoConfig::from_json_str(text, file)
        .map(|inner| Config { inner })
        .map_err(|e| config_error(py, &e))
}

// ------------------------------------------------------- demo, bench ---

fn to_json_text(py: Python<'_>, value: &impl serde::Serialize) -> PyResult<String> {
    serde_json::to_string(value).map_err(|e| error(py, "FirelinkError", e.to_string()))
}

/// Run the demo; the report as JSON text (wrapped by `firelink.run_demo`).
#[pyfunction]
#[pyo3(signature = (port, duration, rate, protocol, firmware, fault, pacing, watchdog_ms, config))]
#[allow(clippy::too_many_arguments)]
fn run_demo_json(
    py: Python<'_>,
    port: &str,
    duration: f64,
    rate: f64,
    protocol: &str,
    firmware: &str,
    fault: &str,
    pacing: Option<&str>,
    watchdog_ms: &Bound<'_, PyAny>,
    config: Option<&Config>,
) -> PyResult<String> {
    let watchdog = watchdog_setting(py, watchdog_ms)?;
    if let Some(w) = watchdog.warning() {
        warn(py, w)?;
    }
    let options = DemoOptions {
        config: config.map_or_else(presets::dvrk_seed000, |c| c.inner.clone()),
        rate_hz: rate,
        protocol: self::protocol(py, Some(protocol))?.unwrap_or(Protocol::Broadcast),
        duration_s: duration,
        port: port
            .parse::<DemoPort>()
            .map_err(|e| error(py, "PortError", e.to_string()))?,
        firmware: profile(py, firmware)?,
        fault: fault
            .parse::<DemoFault>()
            .map_err(|e| bad(py, e.to_string()))?,
        pacing: match pacing {
            None => None,
            Some("virtual") => Some(Pacing::Virtual),
            Some("realtime") => Some(Pacing::WallClock),
            Some(p) => {
                return Err(bad(
                    py,
                    format!("unknown pacing {p:?}: virtual or realtime"),
                ));
            }
        },
        watchdog,
        udp_wait: WaitMode::Blocking,
        stop: None,
    };
    let report = py
        .detach(|| firelink_testbed::demo::run_demo(&options, None, |_| {}))
        .map_err(|e| testbed_error(py, e))?;
    let mut value =
        serde_json::to_value(&report).map_err(|e| error(py, "FirelinkError", e.to_string()))?;
    if let Some(map) = value.as_object_mut() {
        let verdict = report.verdict().err().unwrap_or_else(|| "ok".to_string());
        map.insert("verdict".into(), verdict.into());
    }
    to_json_text(py, &value)
}

/// Run the benchmark; the report as JSON text (wrapped by `firelink.run_bench`).
#[pyfunction]
#[pyo3(signature = (transports, boards, protocols, cycles, firmware, plot))]
fn run_bench_json(
    py: Python<'_>,
    transports: Vec<String>,
    boards: Vec<usize>,
    protocols: Vec<String>,
    cycles: u64,
    firmware: &str,
    plot: Option<std::path::PathBuf>,
) -> PyResult<String> {
    let transports = transports
        .iter()
        .map(|t| {
            BenchTransport::from_name(t)
                .ok_or_else(|| bad(py, format!("unknown transport {t:?}: sim or udp")))
        })
        .collect::<PyResult<Vec<_>>>()?;
    let protocols = protocols
        .iter()
        .map(|p| self::protocol(py, Some(p)).map(|p| p.unwrap_or(Protocol::Broadcast)))
        .collect::<PyResult<Vec<_>>>()?;
    if cycles == 0 || cycles > 1_000_000 {
        return Err(bad(py, format!("cycles = {cycles}: must be 1..=1000000")));
    }
    let options = BenchOptions {
        transports,
        boards,
        protocols,
        cycles,
        firmware: profile(py, firmware)?,
        ..BenchOptions::default()
    };
    let report = py
        .detach(|| firelink_testbed::bench::run_bench(&options, |_, _, _| {}))
        .map_err(|e| testbed_error(py, e))?;
    if let Some(path) = plot {
        py.detach(|| firelink_plot::fig11(&report, &path))
            .map_err(|e| error(py, "FirelinkError", e.to_string()))?;
    }
    to_json_text(py, &report)
}

// ------------------------------------------------------------ packets ---

/// Decode one packet (with `bridge`, a host->bridge datagram): JSON text of
/// its fields (wrapped by `firelink.decode_packet`).
#[pyfunction]
#[pyo3(signature = (data, bridge=false))]
fn decode_packet_json(py: Python<'_>, data: &[u8], bridge: bool) -> PyResult<String> {
    let record =
        packet_json::decode(data, bridge).map_err(|e| error(py, "PacketError", e.to_string()))?;
    to_json_text(py, &record)
}

/// Encode the packet whose fields are `json` (JSON text): its bytes.
#[pyfunction]
#[pyo3(signature = (json, bridge=false))]
fn encode_packet_json<'py>(
    py: Python<'py>,
    json: &str,
    bridge: bool,
) -> PyResult<Bound<'py, PyBytes>> {
    let record: PacketJson =
        serde_json::from_str(json).map_err(|e| error(py, "PacketError", e.to_string()))?;
    let bytes = packet_json::encode(&record, bridge)
        .map_err(|e| error(py, "PacketError", e.to_string()))?;
    Ok(PyBytes::new(py, &bytes))
}

/// The IEEE 1394 CRC-32 of `data`.
#[pyfunction]
fn crc1394(data: &[u8]) -> u32 {
    firelink_wire::crc::crc1394(data)
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
    m.add_function(wrap_pyfunction!(parse_config, m)?)?;
    m.add_function(wrap_pyfunction!(run_demo_json, m)?)?;
    m.add_function(wrap_pyfunction!(run_bench_json, m)?)?;
    m.add_function(wrap_pyfunction!(decode_packet_json, m)?)?;
    m.add_function(wrap_pyfunction!(encode_packet_json, m)?)?;
    m.add_function(wrap_pyfunction!(crc1394, m)?)?;
    Ok(())
}
