//! `firelink._firelink`: the native half of the Python package `firelink`.
//!
//! Thin bindings over the Rust library: ports and discovery
//! ([`firelink_host`]), the I/O system with per-axis data as numpy arrays,
//! register access, seed 001's Snake nodes ([`snake`]), configurations ([`firelink_control::config`]), the demo,
//! the benchmark and the in-process emulator ([`firelink_testbed`]), packet
//! records ([`firelink_host::packet_json`]). Every call that does I/O or
//! simulation releases the GIL; every error becomes one of the package's
//! exceptions (defined in `firelink/_errors.py`) with the library's
//! one-line message. Bad input raises; it never panics: every argument is
//! converted with its name and range first ([`args`]), and long calls
//! return on Ctrl-C ([`interrupt`]).

mod args;
mod interrupt;
mod snake;

use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant};

use numpy::{IntoPyArray, PyArray1};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyString};

use firelink_control::config::{ConfigErrors, IoConfig, presets};
use firelink_control::runner::Pacing;
use firelink_host::io::{IoOptions, IoSystem as HostIoSystem};
use firelink_host::packet_json::{self, PacketJson};
use firelink_host::port::Dest;
use firelink_host::scan::Protocol;
use firelink_host::udp::WaitMode;
use firelink_host::{HostError, Port as HostPort, WatchdogSetting};
use firelink_testbed::TestbedError;
use firelink_testbed::bench::{BenchOptions, BenchTransport};
use firelink_testbed::demo::{DemoFault, DemoOptions};
use firelink_testbed::emulated::Profile;
use firelink_testbed::port_spec::{self, PortSpec, PortSpecError};
use firelink_testbed::ports::{PortOptions, open_bus_port};
use firelink_testbed::rig;

use args::Span;

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
        HostError::Timeout { .. } | HostError::CycleDeadline { .. } => "BusTimeout",
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
        e @ (TestbedError::PortSpec(_) | TestbedError::PortRefused(_)) => {
            error(py, "PortError", e.to_string())
        }
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
    let range = WatchdogSetting::RANGE;
    if let Ok(text) = value.cast::<PyString>() {
        let text = args::string(text)?;
        return WatchdogSetting::parse(&text).map_err(|e| match e {
            firelink_wire::board::registers::WatchdogParseError::NotANumber => bad(
                py,
                format!("watchdog {text:?} is neither \"off\" nor a period in ms {range}"),
            ),
            range_error => bad(py, range_error.to_string()),
        });
    }
    let not_a_period = || {
        bad(
            py,
            format!(
                "watchdog must be a period in ms {range} or \"off\", not {}",
                args::type_name(value)
            ),
        )
    };
    if args::is_bool(value) {
        return Err(not_a_period());
    }
    match value.extract::<f64>() {
        // NaN and every out-of-range period: the setting's own message.
        Ok(ms) => WatchdogSetting::from_ms(ms).map_err(|e| bad(py, e.to_string())),
        Err(e) if e.is_instance_of::<pyo3::exceptions::PyOverflowError>(py) => Err(bad(
            py,
            format!(
                "watchdog period {} ms is out of range: {range}, or \"off\"",
                args::huge(value)
            ),
        )),
        Err(_) => Err(not_a_period()),
    }
}

// ------------------------------------------------------------- ports ---

pub(crate) fn profile(py: Python<'_>, name: &str) -> PyResult<Profile> {
    port_spec::firmware_of(name).ok_or_else(|| {
        error(
            py,
            "PortError",
            format!("unknown firmware {name:?}: expected 7, 8, 9 or seed"),
        )
    })
}

/// Parse a port description with the one grammar every front end shares
/// (`firelink_testbed::port_spec`); `PortError` with the parser's message.
pub(crate) fn parse_port_spec(py: Python<'_>, spec: &str) -> PyResult<PortSpec> {
    spec.parse()
        .map_err(|e: PortSpecError| error(py, "PortError", e.to_string()))
}

/// Open a port for `command` (a Python call that runs no robot of its own:
/// `firelink.open`, `Port`, `IoSystem`): `sim` is seed 000's dVRK.
pub(crate) fn open_port_for(
    py: Python<'_>,
    command: &str,
    spec: &str,
) -> PyResult<(AnyPort, String)> {
    let spec = parse_port_spec(py, spec)?;
    let port = py
        .detach(|| open_bus_port(command, &spec, &PortOptions::default()))
        .map_err(|e| testbed_error(py, e))?;
    Ok((port, spec.to_string()))
}

/// Open a port from its description (see `firelink.open`).
fn open_port(py: Python<'_>, spec: &str) -> PyResult<(AnyPort, String)> {
    open_port_for(py, "firelink.open", spec)
}

/// `firelink.parse_port`: a port description as every front end reads it,
/// written back (`"fw"` is `"fw:0"`, `"udp:localhost"` is
/// `"udp:127.0.0.1:1394"`); opens nothing.
#[pyfunction]
fn parse_port(py: Python<'_>, text: &Bound<'_, PyAny>) -> PyResult<String> {
    let text = args::text(text, "port", port_spec::EXPECTED)?;
    Ok(parse_port_spec(py, &text)?.to_string())
}

/// A physical node ID, 0..=63 (63: broadcast).
fn node(value: &Bound<'_, PyAny>) -> PyResult<Dest> {
    args::int_as(value, "node", 0, 63).map(Dest::node)
}

/// An address in a node's 48-bit space.
fn offset(value: &Bound<'_, PyAny>) -> PyResult<u64> {
    args::int_as(
        value,
        "address",
        0,
        firelink_wire::packet::MAX_OFFSET as i64,
    )
}

/// A quadlet's value, 32 bits.
fn quadlet(value: &Bound<'_, PyAny>) -> PyResult<u32> {
    args::int_as(value, "value", 0, i64::from(u32::MAX))
}

/// A board ID (rotary switch), 0..=15.
fn board_id(value: &Bound<'_, PyAny>) -> PyResult<u8> {
    args::int_as(value, "board ID", 0, 15)
}

/// The longest wait one call may ask for: a day.
const MAX_WAIT_S: f64 = 86_400.0;

/// How much port time one step of a long wait covers (a stop request is
/// checked between steps).
const WAIT_STEP: Duration = Duration::from_millis(50);

/// A wait argument, seconds (0 to a day).
fn wait_arg(value: &Bound<'_, PyAny>) -> PyResult<Duration> {
    let s = args::real(value, "wait", Span::closed(0.0, MAX_WAIT_S, " s"))?;
    Ok(Duration::from_secs_f64(s))
}

/// Let `d` pass on `port`: at once when short, otherwise in steps that
/// Ctrl-C interrupts (a UDP port sleeps in real time; the simulated bus
/// runs its boards).
fn wait_on<P: HostPort + Send + ?Sized>(py: Python<'_>, port: &mut P, d: Duration) -> PyResult<()> {
    if d <= interrupt::POLL {
        py.detach(|| port.wait(d));
        return Ok(());
    }
    interrupt::until_interrupted(py, |stop| {
        let mut left = d;
        while !left.is_zero() && !stop.is_requested() {
            let step = left.min(WAIT_STEP);
            port.wait(step);
            left -= step;
        }
    })
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
    fn new(py: Python<'_>, spec: &Bound<'_, PyAny>) -> PyResult<Port> {
        let Ok(spec) = spec.cast::<PyString>() else {
            return Err(error(
                py,
                "PortError",
                format!(
                    "a port description is a string ({}), not {}",
                    port_spec::EXPECTED,
                    args::type_name(spec)
                ),
            ));
        };
        let (inner, name) = open_port(py, &args::string(spec)?)?;
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

    /// Let `seconds` pass (virtual time on the simulated bus), at most a
    /// day; Ctrl-C interrupts a long wait.
    fn wait(&mut self, py: Python<'_>, seconds: &Bound<'_, PyAny>) -> PyResult<()> {
        let d = wait_arg(seconds)?;
        let port = self.get(py)?;
        wait_on(py, port.as_mut(), d)
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
    fn read_quadlet(
        &mut self,
        py: Python<'_>,
        node: &Bound<'_, PyAny>,
        address: &Bound<'_, PyAny>,
    ) -> PyResult<u32> {
        let (dest, offset) = (self::node(node)?, self::offset(address)?);
        let port = self.get(py)?;
        py.detach(|| port.read_quadlet(dest, offset))
            .map_err(|e| host_error(py, e))
    }

    /// Write one quadlet (node 63: broadcast).
    fn write_quadlet(
        &mut self,
        py: Python<'_>,
        node: &Bound<'_, PyAny>,
        address: &Bound<'_, PyAny>,
        value: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let (dest, offset) = (self::node(node)?, self::offset(address)?);
        let value = quadlet(value)?;
        let port = self.get(py)?;
        py.detach(|| port.write_quadlet(dest, offset, value))
            .map_err(|e| host_error(py, e))
    }

    /// Read `quadlets` quadlets (1..=512) from `address`; the bytes.
    fn read_block<'py>(
        &mut self,
        py: Python<'py>,
        node: &Bound<'_, PyAny>,
        address: &Bound<'_, PyAny>,
        quadlets: &Bound<'_, PyAny>,
    ) -> PyResult<Bound<'py, PyBytes>> {
        let (dest, offset) = (self::node(node)?, self::offset(address)?);
        let quadlets: usize = args::int_as(quadlets, "quadlets", 1, 512)?;
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
        node: &Bound<'_, PyAny>,
        address: &Bound<'_, PyAny>,
        data: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let (dest, offset) = (self::node(node)?, self::offset(address)?);
        let data = args::bytes(data, "data")?;
        if data.is_empty() || data.len() % 4 != 0 || data.len() > 2048 {
            return Err(bad(
                py,
                format!(
                    "a block write of {} bytes is refused: it must be 4 to 2048 bytes, whole quadlets",
                    data.len()
                ),
            ));
        }
        let port = self.get(py)?;
        py.detach(|| port.write_block(dest, offset, &data))
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

/// The port a system takes: a description (opened here with `open`) or a
/// `Port` (taken from it).
fn port_arg(
    py: Python<'_>,
    port: &Bound<'_, PyAny>,
    what: &str,
    open: impl FnOnce(&str) -> PyResult<AnyPort>,
) -> PyResult<AnyPort> {
    match port.cast::<PyString>() {
        Ok(text) => open(&args::string(text)?),
        Err(_) => take_port(py, port, what),
    }
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

/// The protocols' names, for messages.
const PROTOCOLS: &str = "sequential, sequential-read-broadcast-write or broadcast";

fn protocol(py: Python<'_>, name: &str) -> PyResult<Protocol> {
    Protocol::from_name(name)
        .ok_or_else(|| bad(py, format!("unknown protocol {name:?}: {PROTOCOLS}")))
}

/// An optional protocol argument (`None`: the best the boards support).
fn protocol_arg(py: Python<'_>, value: Option<&Bound<'_, PyAny>>) -> PyResult<Option<Protocol>> {
    args::opt_text(value, "protocol", PROTOCOLS)?
        .map(|n| protocol(py, &n))
        .transpose()
}

impl IoSystem {
    fn board_index(
        &mut self,
        py: Python<'_>,
        board: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Vec<usize>> {
        match args::opt_int_as::<u8>(board, "board ID", 0, 15)? {
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
}

#[pymethods]
impl IoSystem {
    /// Take `port` (a `Port` or a port description), scan it and choose the
    /// protocol (the best the boards support, or `protocol`).
    #[new]
    #[pyo3(signature = (port, protocol=None))]
    fn new(
        py: Python<'_>,
        port: &Bound<'_, PyAny>,
        protocol: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<IoSystem> {
        let chosen = protocol_arg(py, protocol)?;
        let inner = port_arg(py, port, "IoSystem", |text| {
            Ok(open_port_for(py, "firelink.IoSystem", text)?.0)
        })?;
        let config = IoOptions {
            protocol: chosen,
            ..IoOptions::default()
        };
        // A scan waits out a time-out per absent node: Ctrl-C returns at
        // once (the scan ends on its own and drops the port).
        let (io, _) =
            interrupt::abandon_on_interrupt(py, move || HostIoSystem::open(inner, config))?
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

    /// Let `seconds` pass (virtual time on the simulated bus), at most a
    /// day; Ctrl-C interrupts a long wait.
    fn wait(&mut self, py: Python<'_>, seconds: &Bound<'_, PyAny>) -> PyResult<()> {
        let d = wait_arg(seconds)?;
        let io = exclusive(&mut self.io);
        wait_on(py, io.port_mut().as_mut(), d)
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

    /// Run `cycles` (0 to 10^9) read+write cycles in Rust with the GIL
    /// released; the wall time they took, seconds (the baseline of the
    /// Python overhead benchmark). Ctrl-C stops them.
    fn run_cycles(&mut self, py: Python<'_>, cycles: &Bound<'_, PyAny>) -> PyResult<f64> {
        let cycles: u64 = args::int_as(cycles, "cycles", 0, MAX_CYCLES)?;
        let io = exclusive(&mut self.io);
        interrupt::until_interrupted(py, |stop| {
            let start = Instant::now();
            for _ in 0..cycles {
                if stop.is_requested() {
                    break;
                }
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
    /// Any array of integers (numpy of any integer type, a list).
    fn set_dac(&mut self, py: Python<'_>, bits: &Bound<'_, PyAny>) -> PyResult<()> {
        let bits = args::int_array(bits, "set_dac", self.axes.len())?;
        if let Some(v) = bits.iter().find(|v| !(0..=65535).contains(*v)) {
            return Err(bad(
                py,
                format!("set_dac: DAC value {v} is out of range: it must be 0 to 65535"),
            ));
        }
        for (&(b, a), &v) in self.axes.iter().zip(&bits) {
            if let Some(board) = exclusive(&mut self.io).boards_mut().get_mut(b) {
                board.set_dac(a, v as u16).map_err(|e| host_error(py, e))?;
            }
        }
        Ok(())
    }

    /// Set every axis's motor current command, amps, with the QLA's
    /// nominal scaling (bits = (amps + 6.25) * 65536 / 12.5), for the next
    /// write. Values outside +-6.25 A are refused. Any array of numbers
    /// (numpy of any float or integer type, a list).
    fn set_current(&mut self, py: Python<'_>, amps: &Bound<'_, PyAny>) -> PyResult<()> {
        let amps = args::real_array(amps, "set_current", self.axes.len())?;
        if let Some(v) = amps.iter().find(|v| !(v.is_finite() && v.abs() <= 6.25)) {
            return Err(bad(
                py,
                format!(
                    "set_current: {} A is out of range: it must be from -6.25 to 6.25 A",
                    firelink_wire::human::Number(*v)
                ),
            ));
        }
        for (&(b, a), &v) in self.axes.iter().zip(&amps) {
            let bits = ((v + 6.25) * 65536.0 / 12.5).round().clamp(0.0, 65535.0) as u16;
            if let Some(board) = exclusive(&mut self.io).boards_mut().get_mut(b) {
                board.set_dac(a, bits).map_err(|e| host_error(py, e))?;
            }
        }
        Ok(())
    }

    /// Request motor power on or off (every board, or `board`) with the next write.
    #[pyo3(signature = (on, board=None))]
    fn set_power(
        &mut self,
        py: Python<'_>,
        on: &Bound<'_, PyAny>,
        board: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let on = args::flag(on, "on")?;
        for i in self.board_index(py, board)? {
            exclusive(&mut self.io).boards_mut()[i].set_power(on);
        }
        Ok(())
    }

    /// Request the safety relay on or off with the next write.
    #[pyo3(signature = (on, board=None))]
    fn set_relay(
        &mut self,
        py: Python<'_>,
        on: &Bound<'_, PyAny>,
        board: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let on = args::flag(on, "on")?;
        for i in self.board_index(py, board)? {
            exclusive(&mut self.io).boards_mut()[i].set_relay(on);
        }
        Ok(())
    }

    /// Request every amplifier (of every board, or `board`) on or off.
    #[pyo3(signature = (on, board=None))]
    fn set_amplifiers(
        &mut self,
        py: Python<'_>,
        on: &Bound<'_, PyAny>,
        board: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let on = args::flag(on, "on")?;
        for i in self.board_index(py, board)? {
            exclusive(&mut self.io).boards_mut()[i].set_all_amps(on);
        }
        Ok(())
    }

    /// Set every board's watchdog: a period in milliseconds (one 5.208 us
    /// tick to 341.32 ms) or `"off"` (a lost host then leaves the
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
    fn read_register(
        &mut self,
        py: Python<'_>,
        board_id: &Bound<'_, PyAny>,
        offset: &Bound<'_, PyAny>,
    ) -> PyResult<u32> {
        let (board_id, offset) = (self::board_id(board_id)?, self::offset(offset)?);
        let io = exclusive(&mut self.io);
        py.detach(|| io.read_register(board_id, offset))
            .map_err(|e| host_error(py, e))
    }

    /// Write a register of board `board_id`.
    fn write_register(
        &mut self,
        py: Python<'_>,
        board_id: &Bound<'_, PyAny>,
        offset: &Bound<'_, PyAny>,
        value: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let (board_id, offset) = (self::board_id(board_id)?, self::offset(offset)?);
        let value = quadlet(value)?;
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
    /// or seed) for the robots of `config` (a `Config` or a configuration
    /// file; default: seed 000's dVRK);
    /// with `robot="snake"`, one Snake node per board of `config`
    /// (default: the six of `configs/snake-seed001.json`) instead, for
    /// `SnakeSystem` (`boards` and `firmware` do not apply).
    #[new]
    #[pyo3(signature = (boards=None, firmware=None, *, robot=None, config=None))]
    fn new(
        py: Python<'_>,
        boards: Option<&Bound<'_, PyAny>>,
        firmware: Option<&Bound<'_, PyAny>>,
        robot: Option<&Bound<'_, PyAny>>,
        config: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Emulator> {
        let boards: usize = args::opt_int_as(boards, "boards", 1, 16)?.unwrap_or(8);
        let firmware = firmware
            .filter(|f| !f.is_none())
            .map_or(Ok(Profile::Rev8), args::firmware)?;
        let robot = args::opt_text(robot, "robot", "qla or snake")?;
        let config = config_arg(py, config)?;
        let start = match robot.as_deref().unwrap_or("qla") {
            "qla" => {
                let dvrk = config.unwrap_or_else(presets::dvrk_seed000);
                rig::RigBuilder::qla(rig::board_configs(&dvrk, firmware, boards))
            }
            "snake" => {
                let snake = config.unwrap_or_else(presets::snake_seed001);
                let configs = firelink_testbed::snake::node_configs(&snake, 1)
                    .map_err(|e| testbed_error(py, e))?;
                rig::RigBuilder::snake(configs)
            }
            other => {
                return Err(bad(py, format!("unknown robot {other:?}: qla or snake")));
            }
        };
        let emu = py
            .detach(|| rig::Emulator::start_rig(start))
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
    #[pyo3(signature = (timeout = None))]
    fn port(&self, py: Python<'_>, timeout: Option<&Bound<'_, PyAny>>) -> PyResult<Port> {
        let emu = self
            .inner
            .as_ref()
            .ok_or_else(|| error(py, "EmulatorClosed", "the emulator is stopped".to_string()))?;
        let timeout = match timeout.filter(|t| !t.is_none()) {
            None => 1.0,
            Some(t) => args::real(t, "timeout", Span::above(0.0, 60.0, " s"))?,
        };
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

/// A path argument: a `str` or an `os.PathLike`.
fn path_arg(value: &Bound<'_, PyAny>, what: &str) -> PyResult<std::path::PathBuf> {
    if value.is_instance_of::<PyBytes>() {
        return Err(bad(
            value.py(),
            format!("{what} must be a str or os.PathLike, not bytes"),
        ));
    }
    value.extract::<std::path::PathBuf>().map_err(|_| {
        bad(
            value.py(),
            format!(
                "{what} must be a str or os.PathLike, not {}",
                args::type_name(value)
            ),
        )
    })
}

/// A configuration argument: a `Config`, or a file's path (loaded here,
/// `ConfigError` when invalid); `None`: absent.
pub(crate) fn config_arg(
    py: Python<'_>,
    value: Option<&Bound<'_, PyAny>>,
) -> PyResult<Option<IoConfig>> {
    let Some(value) = value.filter(|v| !v.is_none()) else {
        return Ok(None);
    };
    if let Ok(c) = value.cast::<Config>() {
        return Ok(Some(c.get().inner.clone()));
    }
    let path = path_arg(value, "config (a firelink.Config or a configuration file)")?;
    IoConfig::load(&path)
        .map(Some)
        .map_err(|e| config_error(py, &e))
}

/// Load and validate a configuration file; raises `ConfigError`.
#[pyfunction]
fn load_config(py: Python<'_>, path: &Bound<'_, PyAny>) -> PyResult<Config> {
    let path = path_arg(path, "path")?;
    IoConfig::load(&path)
        .map(|inner| Config { inner })
        .map_err(|e| config_error(py, &e))
}

/// Parse and validate configuration text (a `str`, or UTF-8 `bytes`);
/// raises `ConfigError`.
#[pyfunction]
#[pyo3(signature = (text, file=None))]
fn parse_config(
    py: Python<'_>,
    text: &Bound<'_, PyAny>,
    file: Option<&Bound<'_, PyAny>>,
) -> PyResult<Config> {
    let file = args::opt_text(file, "file", "the name errors give")?
        .unwrap_or_else(|| "<string>".to_string());
    let text = match text.cast::<PyBytes>() {
        Ok(b) => String::from_utf8(b.as_bytes().to_vec()).map_err(|e| {
            error(
                py,
                "ConfigError",
                format!("{file}: the configuration is not UTF-8 text ({e})"),
            )
        })?,
        Err(_) => args::text(text, "text", "the configuration's JSON")?,
    };
    IoConfig::from_json_str(&text, &file)
        .map(|inner| Config { inner })
        .map_err(|e| config_error(py, &e))
}

// ------------------------------------------------------- demo, bench ---

fn to_json_text(py: Python<'_>, value: &impl serde::Serialize) -> PyResult<String> {
    serde_json::to_string(value).map_err(|e| error(py, "FirelinkError", e.to_string()))
}

/// The longest demo, seconds of motion (as the command line's).
const MAX_DEMO_S: f64 = 86_400.0;

/// The most cycles one call runs or measures (as the command line's).
const MAX_CYCLES: i64 = 1_000_000_000;

/// The most cycles per benchmark point.
const MAX_BENCH_CYCLES: i64 = 1_000_000;

/// Run the demo; the report as JSON text (wrapped by `firelink.run_demo`).
/// Ctrl-C stops the robot at its next cycle (the boards it powered are
/// powered down) and raises `KeyboardInterrupt`.
#[pyfunction]
#[pyo3(signature = (port, duration, rate, protocol, firmware, fault, pacing, watchdog_ms, config))]
#[allow(clippy::too_many_arguments)]
fn run_demo_json(
    py: Python<'_>,
    port: &Bound<'_, PyAny>,
    duration: &Bound<'_, PyAny>,
    rate: &Bound<'_, PyAny>,
    protocol: &Bound<'_, PyAny>,
    firmware: &Bound<'_, PyAny>,
    fault: &Bound<'_, PyAny>,
    pacing: Option<&Bound<'_, PyAny>>,
    watchdog_ms: &Bound<'_, PyAny>,
    config: Option<&Bound<'_, PyAny>>,
) -> PyResult<String> {
    let port = args::text(port, "port", port_spec::EXPECTED)?;
    let duration_s = args::real(duration, "duration", Span::above(0.0, MAX_DEMO_S, " s"))?;
    let rate_hz = args::real(rate, "rate", Span::closed(1.0, 100_000.0, " Hz"))?;
    let protocol = self::protocol(py, &args::text(protocol, "protocol", PROTOCOLS)?)?;
    let firmware = args::firmware(firmware)?;
    let faults = "none, stop-host, corrupt-query, board-loss or following-error";
    let fault = args::text(fault, "fault", faults)?
        .parse::<DemoFault>()
        .map_err(|e| bad(py, e.to_string()))?;
    let pacing = match args::opt_text(pacing, "pacing", "virtual or realtime")?.as_deref() {
        None => None,
        Some("virtual") => Some(Pacing::Virtual),
        Some("realtime") => Some(Pacing::WallClock),
        Some(p) => {
            return Err(bad(
                py,
                format!("unknown pacing {p:?}: virtual or realtime"),
            ));
        }
    };
    let watchdog = watchdog_setting(py, watchdog_ms)?;
    let config = config_arg(py, config)?;
    let options = DemoOptions {
        config: config.unwrap_or_else(presets::dvrk_seed000),
        rate_hz,
        protocol,
        duration_s,
        port: parse_port_spec(py, &port)?,
        firmware,
        fault,
        pacing,
        watchdog,
        udp_wait: WaitMode::Blocking,
    };
    if let Some(w) = watchdog.warning() {
        warn(py, w)?;
    }
    let report = interrupt::until_interrupted(py, |stop| {
        firelink_testbed::demo::run_demo_until(&options, stop, None, |_| {})
    })?
    .map_err(|e| testbed_error(py, e))?;
    let mut value =
        serde_json::to_value(&report).map_err(|e| error(py, "FirelinkError", e.to_string()))?;
    if let Some(map) = value.as_object_mut() {
        let verdict = report.verdict().err().unwrap_or_else(|| "ok".to_string());
        map.insert("verdict".into(), verdict.into());
    }
    to_json_text(py, &value)
}

/// The items of a list argument (any iterable but a string; a string is
/// one item), at most `max` of them: an endless iterator is refused, not
/// followed.
fn items<'py>(
    value: &Bound<'py, PyAny>,
    what: &str,
    max: usize,
) -> PyResult<Vec<Bound<'py, PyAny>>> {
    if value.is_instance_of::<PyString>() {
        return Ok(vec![value.clone()]);
    }
    let iter = value.try_iter().map_err(|_| {
        bad(
            value.py(),
            format!("{what} must be a list, not {}", args::type_name(value)),
        )
    })?;
    let mut out = Vec::new();
    for item in iter {
        if out.len() == max {
            return Err(bad(
                value.py(),
                format!("{what} has more than {max} entries"),
            ));
        }
        out.push(item?);
    }
    Ok(out)
}

/// Run the benchmark; the report as JSON text (wrapped by `firelink.run_bench`).
/// Ctrl-C returns at once with `KeyboardInterrupt` (the benchmark's thread,
/// on emulated boards only, finishes its work on its own).
#[pyfunction]
#[pyo3(signature = (transports, boards, protocols, cycles, firmware, plot))]
fn run_bench_json(
    py: Python<'_>,
    transports: &Bound<'_, PyAny>,
    boards: &Bound<'_, PyAny>,
    protocols: &Bound<'_, PyAny>,
    cycles: &Bound<'_, PyAny>,
    firmware: &Bound<'_, PyAny>,
    plot: Option<&Bound<'_, PyAny>>,
) -> PyResult<String> {
    let transports = items(transports, "transports", 8)?
        .iter()
        .map(|t| {
            let name = args::text(t, "a transport", BenchTransport::NAMES)?;
            BenchTransport::from_name(&name).ok_or_else(|| {
                bad(
                    py,
                    format!("unknown transport {name:?}: {}", BenchTransport::NAMES),
                )
            })
        })
        .collect::<PyResult<Vec<_>>>()?;
    let boards = items(boards, "boards", 64)?
        .iter()
        .map(|b| args::int_as::<usize>(b, "a board count", 1, 62))
        .collect::<PyResult<Vec<_>>>()?;
    let protocols = items(protocols, "protocols", 8)?
        .iter()
        .map(|p| protocol(py, &args::text(p, "a protocol", PROTOCOLS)?))
        .collect::<PyResult<Vec<_>>>()?;
    let cycles: u64 = args::int_as(cycles, "cycles", 1, MAX_BENCH_CYCLES)?;
    let plot = match plot.filter(|p| !p.is_none()) {
        None => None,
        Some(p) => Some(path_arg(p, "plot")?),
    };
    let options = BenchOptions {
        transports,
        boards,
        protocols,
        cycles,
        firmware: args::firmware(firmware)?,
        ..BenchOptions::default()
    };
    // Checked here too, so that a refusal is not left to the worker.
    firelink_testbed::bench::check_board_counts(&options.boards).map_err(|e| bad(py, e))?;
    if options.transports.is_empty() || options.protocols.is_empty() {
        return Err(bad(
            py,
            "run_bench needs at least one transport and one protocol",
        ));
    }
    let outcome = interrupt::abandon_on_interrupt(py, move || {
        let report = firelink_testbed::bench::run_bench(&options, |_, _, _| {})
            .map_err(|e| e.to_string())?;
        if let Some(path) = plot {
            firelink_plot::fig11(&report, &path).map_err(|e| e.to_string())?;
        }
        serde_json::to_string(&report).map_err(|e| e.to_string())
    })?;
    outcome.map_err(|e| error(py, "FirelinkError", e))
}

// ------------------------------------------------------------ packets ---

/// Decode one packet (with `bridge`, a host->bridge datagram): JSON text of
/// its fields (wrapped by `firelink.decode_packet`).
#[pyfunction]
#[pyo3(signature = (data, bridge=None))]
fn decode_packet_json(
    py: Python<'_>,
    data: &Bound<'_, PyAny>,
    bridge: Option<&Bound<'_, PyAny>>,
) -> PyResult<String> {
    let Ok(data) = args::bytes(data, "data") else {
        return Err(error(
            py,
            "PacketError",
            format!("decode_packet takes bytes, not {}", args::type_name(data)),
        ));
    };
    let bridge = bridge.map_or(Ok(false), |b| args::flag(b, "bridge"))?;
    let record =
        packet_json::decode(&data, bridge).map_err(|e| error(py, "PacketError", e.to_string()))?;
    to_json_text(py, &record)
}

/// Encode the packet whose fields are `json` (JSON text): its bytes.
#[pyfunction]
#[pyo3(signature = (json, bridge=None))]
fn encode_packet_json<'py>(
    py: Python<'py>,
    json: &Bound<'py, PyAny>,
    bridge: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyBytes>> {
    let json = args::text(json, "the packet's fields", "JSON text")?;
    let bridge = bridge.map_or(Ok(false), |b| args::flag(b, "bridge"))?;
    let record: PacketJson =
        serde_json::from_str(&json).map_err(|e| error(py, "PacketError", e.to_string()))?;
    let bytes = packet_json::encode(&record, bridge)
        .map_err(|e| error(py, "PacketError", e.to_string()))?;
    Ok(PyBytes::new(py, &bytes))
}

/// The IEEE 1394 CRC-32 of `data` (bytes, bytearray or memoryview).
#[pyfunction]
fn crc1394(data: &Bound<'_, PyAny>) -> PyResult<u32> {
    Ok(firelink_wire::crc::crc1394(&args::bytes(data, "data")?))
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
