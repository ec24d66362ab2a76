//! The in-process emulator (`Emulator`): emulated boards behind a UDP
//! socket, for a `with` block.

use pyo3::prelude::*;
use pyo3::types::PyDict;

use firelink_control::config::presets;
use firelink_testbed::emulated::Profile;
use firelink_testbed::rig;

use crate::args::{self, Span};
use crate::config::config_arg;
use crate::errors::{bad, error, testbed_error};
use crate::ports::Port;

/// An in-process `firelink emulate`: emulated boards behind a UDP bridge
/// on 127.0.0.1. A context manager: `with Emulator(boards=8) as emu:`.
#[pyclass(module = "firelink._firelink")]
pub(crate) struct Emulator {
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
        let boards: usize =
            args::opt_int_in(boards, "boards", firelink_testbed::limits::BOARD_COUNT)?.unwrap_or(8);
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
        Ok(Port::wrap(Box::new(port), self.address.clone()))
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
