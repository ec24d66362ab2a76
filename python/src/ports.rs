//! Ports and discovery: opening a port from its description (the one
//! grammar of `firelink_testbed::port_spec`), `Port`, `Board`, and the
//! argument converters for nodes, offsets and quadlets.

use std::sync::Mutex;
use std::time::Duration;

use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyString};

use firelink_host::Port as HostPort;
use firelink_host::port::Dest;
use firelink_testbed::port_spec::{self, PortSpec, PortSpecError};
use firelink_testbed::ports::{PortOptions, open_bus_port};

use crate::args::{self, Span};
use crate::errors::{bad, error, host_error, testbed_error};
use crate::{AnyPort, exclusive, interrupt};
use firelink_testbed::limits;

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
pub(crate) fn parse_port(py: Python<'_>, text: &Bound<'_, PyAny>) -> PyResult<String> {
    let text = args::text(text, "port", port_spec::EXPECTED)?;
    Ok(parse_port_spec(py, &text)?.to_string())
}

/// A physical node ID, 0..=63 (63: broadcast).
pub(crate) fn node(value: &Bound<'_, PyAny>) -> PyResult<Dest> {
    args::int_in(value, "node", limits::NODE_ID).map(Dest::node)
}

/// An address in a node's 48-bit space.
pub(crate) fn offset(value: &Bound<'_, PyAny>) -> PyResult<u64> {
    args::int_as(
        value,
        "address",
        0,
        firelink_wire::packet::MAX_OFFSET as i64,
    )
}

/// A quadlet's value, 32 bits.
pub(crate) fn quadlet(value: &Bound<'_, PyAny>) -> PyResult<u32> {
    args::int_as(value, "value", 0, i64::from(u32::MAX))
}

/// A board ID (rotary switch), 0..=15.
pub(crate) fn board_id(value: &Bound<'_, PyAny>) -> PyResult<u8> {
    args::int_in(value, "board ID", limits::BOARD_ID)
}

/// The longest wait one call may ask for: a day.
const MAX_WAIT_S: f64 = 86_400.0;

/// How much port time one step of a long wait covers (a stop request is
/// checked between steps).
const WAIT_STEP: Duration = Duration::from_millis(50);

/// A wait argument, seconds (0 to a day).
pub(crate) fn wait_arg(value: &Bound<'_, PyAny>) -> PyResult<Duration> {
    let s = args::real(value, "wait", Span::closed(0.0, MAX_WAIT_S, " s"))?;
    Ok(Duration::from_secs_f64(s))
}

/// Let `d` pass on `port`: at once when short, otherwise in steps that
/// Ctrl-C interrupts (a UDP port sleeps in real time; the simulated bus
/// runs its boards).
pub(crate) fn wait_on<P: HostPort + Send + ?Sized>(
    py: Python<'_>,
    port: &mut P,
    d: Duration,
) -> PyResult<()> {
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
pub(crate) struct Board {
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

impl From<&firelink_host::qla::board::BoardInfo> for Board {
    fn from(b: &firelink_host::qla::board::BoardInfo) -> Self {
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
pub(crate) struct Port {
    /// The mutex is never contended (PyO3 hands out `&mut self` one at a
    /// time); it makes the class `Sync`, as PyO3 requires.
    inner: Mutex<Option<AnyPort>>,
    name: String,
}

impl Port {
    /// A `Port` over an open port, shown to Python as `name`.
    pub(crate) fn wrap(inner: AnyPort, name: String) -> Port {
        Port {
            inner: Mutex::new(Some(inner)),
            name,
        }
    }

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
        Ok(Port::wrap(inner, name))
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
            .detach(|| firelink_host::qla::scan::scan(port))
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
        let quadlets: usize = args::int_in(quadlets, "quadlets", limits::QUADLETS)?;
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
pub(crate) fn port_arg(
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
