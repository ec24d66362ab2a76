//! The I/O system (`IoSystem`): per-axis data as numpy arrays, cycles,
//! statistics.

use std::sync::Mutex;
use std::time::Instant;

use numpy::{IntoPyArray, PyArray1};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use firelink_host::Port as HostPort;
use firelink_host::qla::io::{IoOptions, IoSystem as HostIoSystem};
use firelink_host::qla::scan::Protocol;

use crate::args;
use crate::args::{MAX_CYCLES, watchdog_setting};
use crate::errors::{bad, host_error, warn};
use crate::ports::{Board, board_id, offset, open_port_for, port_arg, quadlet, wait_arg, wait_on};
use crate::{AnyPort, exclusive, interrupt};

/// The boards' I/O: one cycle reads every board and writes every board.
#[pyclass(module = "firelink._firelink")]
pub(crate) struct IoSystem {
    /// Never contended (see [`crate::ports::Port`]).
    io: Mutex<HostIoSystem<AnyPort>>,
    /// (board index, axis) of every axis, in board order.
    axes: Vec<(usize, usize)>,
}

/// The protocols' names, for messages.
pub(crate) const PROTOCOLS: &str = "sequential, sequential-read-broadcast-write or broadcast";

pub(crate) fn protocol(py: Python<'_>, name: &str) -> PyResult<Protocol> {
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
    /// Apply `request` to every board, or to the board whose ID is `board`
    /// (`InvalidRequest` if this system has none); nothing is applied when
    /// the argument is refused.
    fn request_on_boards(
        &mut self,
        py: Python<'_>,
        board: Option<&Bound<'_, PyAny>>,
        request: impl Fn(&mut firelink_host::qla::board::BoardIo),
    ) -> PyResult<()> {
        let id = args::opt_int_in::<u8>(board, "board ID", firelink_testbed::limits::BOARD_ID)?;
        let boards = exclusive(&mut self.io).boards_mut();
        match id {
            None => boards.iter_mut().for_each(request),
            Some(id) => match boards.iter_mut().find(|b| b.board_id() == id) {
                Some(b) => request(b),
                None => return Err(bad(py, format!("no board {id} in this system"))),
            },
        }
        Ok(())
    }

    fn per_axis<T: Copy + Default>(
        &mut self,
        f: impl Fn(&firelink_host::qla::board::BoardIo, usize) -> Option<T>,
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
        self.request_on_boards(py, board, |b| b.set_power(on))
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
        self.request_on_boards(py, board, |b| b.set_relay(on))
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
        self.request_on_boards(py, board, |b| b.set_all_amps(on))
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
pub(crate) fn cycle_result(r: &firelink_host::cycle_report::CycleReport) -> (bool, f64) {
    (r.all_ok(), r.io_time().as_secs_f64() * 1e6)
}

/// Error counters as a dict (`IoSystem.stats`, `SnakeSystem.stats`).
pub(crate) fn stats_dict<'py>(
    py: Python<'py>,
    s: &firelink_host::cycle_report::IoStats,
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
