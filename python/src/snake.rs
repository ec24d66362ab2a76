//! `firelink.SnakeSystem`: seed 001's three-layer API for its Snake robot
//! nodes ([`firelink_host::snake`]) from Python.
//!
//! The same patterns as the I/O system: a port description (`"sim"`: the
//! configuration's emulated Snake nodes on the simulated bus; or
//! `"udp:HOST[:PORT]"`) or a `Port`; the GIL released around every bus
//! transaction; per-axis data as numpy arrays (seven axes per node,
//! channels 1..=7 of each node in board-ID order); every error one of the
//! package's exceptions. Arguments are converted by [`crate::args`], so a
//! wrong type or an out-of-range value raises `InvalidRequest` naming it
//! (never `TypeError`, never `OverflowError`, never a panic).

use std::sync::Mutex;

use numpy::{IntoPyArray, PyArray1};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use firelink_control::config::{IoConfig, presets};
use firelink_host::snake::{EepromIndex, SnakeNodeIo, SnakeSystem as HostSnakeSystem};
use firelink_testbed::port_spec::PortKind;
use firelink_wire::snake::CHANNELS;
use firelink_wire::snake::registers::{PotOutputs, PowerControl, Wiper};

use crate::args::{self, Span};
use crate::errors::{bad, error, host_error, testbed_error};
use crate::io_system::{cycle_result, stats_dict};
use crate::{AnyPort, exclusive, interrupt};

/// An argument as given, converted (with its name and range) where it is
/// used: its extraction never fails, so PyO3 raises no `TypeError` first.
struct Arg<'py>(Bound<'py, PyAny>);

impl<'a, 'py> FromPyObject<'a, 'py> for Arg<'py> {
    type Error = PyErr;

    fn extract(obj: pyo3::Borrowed<'a, 'py, PyAny>) -> PyResult<Arg<'py>> {
        Ok(Arg(obj.to_owned()))
    }
}

/// `v` as a `T` when it is an integer in `lo..=hi`; otherwise
/// `InvalidRequest` naming `what` and the range.
fn ranged<T: TryFrom<i64>>(
    _py: Python<'_>,
    v: Arg<'_>,
    lo: i64,
    hi: i64,
    what: &str,
) -> PyResult<T> {
    args::int_as(&v.0, what, lo, hi)
}

fn board_id(_py: Python<'_>, v: Arg<'_>) -> PyResult<u8> {
    args::int_in(&v.0, "board ID", firelink_testbed::limits::BOARD_ID)
}

fn channel(py: Python<'_>, v: Arg<'_>) -> PyResult<u8> {
    ranged(py, v, 1, CHANNELS as i64, "Snake channel")
}

fn code(py: Python<'_>, v: Arg<'_>, what: &str) -> PyResult<u16> {
    ranged(py, v, 0, 0xFFFF, what)
}

/// A flag argument (`True`/`False` only).
fn flag(v: Arg<'_>, what: &str) -> PyResult<bool> {
    args::flag(&v.0, what)
}

/// Open the Snake nodes' port: plain `"sim"` builds `config`'s nodes
/// (default: seed 001's six) on the simulated bus; `"udp:..."` and `"fw"`
/// as everywhere else; `sim:N[:FW]` and `emulate` refused.
fn open_snake_port(py: Python<'_>, spec: &str, config: &IoConfig) -> PyResult<(AnyPort, String)> {
    const COMMAND: &str = "firelink.SnakeSystem";
    let parsed = crate::ports::parse_port_spec(py, spec)?;
    let refused = parsed
        .refuse_unless(COMMAND, &[PortKind::Sim, PortKind::Udp, PortKind::Fw])
        .and_then(|()| {
            parsed.refuse_board_count(
                COMMAND,
                "Snake nodes come from the configuration and have no QLA firmware",
            )
        });
    if let Err(r) = refused {
        return Err(error(py, "PortError", r.to_string()));
    }
    if !parsed.is_sim() {
        return crate::ports::open_port_for(py, COMMAND, spec);
    }
    let nodes =
        firelink_testbed::snake::node_configs(config, 1).map_err(|e| testbed_error(py, e))?;
    let port = py
        .detach(|| firelink_testbed::snake::sim_port(nodes, false, None))
        .map_err(|e| testbed_error(py, e))?;
    Ok((Box::new(port), parsed.to_string()))
}

/// A Snake node found by discovery.
#[pyclass(frozen, get_all, module = "firelink._firelink")]
#[derive(Clone)]
struct SnakeNode {
    /// Board ID from the rotary switch, 0..=15.
    board_id: u8,
    /// Physical node ID in the current bus generation.
    node: u8,
    /// The version register (Snake signature and revision).
    version: u32,
    /// Channels (axes) of the node: 7.
    channels: usize,
}

#[pymethods]
impl SnakeNode {
    fn __repr__(&self) -> String {
        format!(
            "SnakeNode(board_id={}, node={}, version={:#x}, channels={})",
            self.board_id, self.node, self.version, self.channels
        )
    }
}

impl From<&SnakeNodeIo> for SnakeNode {
    fn from(n: &SnakeNodeIo) -> Self {
        SnakeNode {
            board_id: n.board_id(),
            node: n.info().node,
            version: n.info().version,
            channels: CHANNELS,
        }
    }
}

/// Seed 001's Snake robot nodes as one system: `latch_all_inputs()` then
/// `apply_all_outputs()` each cycle, and the node's Get/Set list.
#[pyclass(module = "firelink._firelink")]
pub(crate) struct SnakeSystem {
    /// Never contended (see `Port`).
    sys: Mutex<HostSnakeSystem<AnyPort>>,
}

impl SnakeSystem {
    fn sys(&mut self) -> &mut HostSnakeSystem<AnyPort> {
        exclusive(&mut self.sys)
    }

    /// Node-layer values of every axis (node order, channels 1..=7); an
    /// unreadable value is the type's default.
    fn per_axis<T: Copy + Default>(
        &mut self,
        f: impl Fn(&SnakeNodeIo, u8) -> firelink_host::error::Result<T>,
    ) -> Vec<T> {
        self.sys()
            .nodes()
            .iter()
            .flat_map(|n| (1..=CHANNELS as u8).map(move |ch| (n, ch)))
            .map(|(n, ch)| f(n, ch).unwrap_or_default())
            .collect()
    }

    /// Run a node transaction with the GIL released; errors as exceptions.
    fn at_once<T: Send>(
        &mut self,
        py: Python<'_>,
        f: impl FnOnce(&mut HostSnakeSystem<AnyPort>) -> firelink_host::error::Result<T> + Send,
    ) -> PyResult<T> {
        let sys = self.sys();
        py.detach(|| f(sys)).map_err(|e| host_error(py, e))
    }

    fn node_mut(&mut self, py: Python<'_>, board: u8) -> PyResult<&mut SnakeNodeIo> {
        self.sys()
            .node_mut(board)
            .ok_or_else(|| bad(py, format!("no Snake node {board} in this system")))
    }

    fn board_ids(&mut self, py: Python<'_>, board: Option<Arg<'_>>) -> PyResult<Vec<u8>> {
        match board.filter(|b| !b.0.is_none()) {
            None => Ok(self
                .sys()
                .nodes()
                .iter()
                .map(SnakeNodeIo::board_id)
                .collect()),
            Some(b) => {
                let id = board_id(py, b)?;
                self.node_mut(py, id)?;
                Ok(vec![id])
            }
        }
    }
}

#[pymethods]
impl SnakeSystem {
    /// Take `port` (a `Port` or a description: `"sim"` for the emulated
    /// nodes of `config`, default seed 001's six, on the simulated bus;
    /// `"udp:HOST[:PORT]"`) and discover its Snake nodes.
    #[new]
    #[pyo3(signature = (port=None, config=None))]
    fn new(
        py: Python<'_>,
        port: Option<&Bound<'_, PyAny>>,
        config: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<SnakeSystem> {
        let config = crate::config::config_arg(py, config)?.unwrap_or_else(presets::snake_seed001);
        let inner: AnyPort = match port.filter(|p| !p.is_none()) {
            None => open_snake_port(py, "sim", &config)?.0,
            Some(p) => crate::ports::port_arg(py, p, "SnakeSystem", |text| {
                Ok(open_snake_port(py, text, &config)?.0)
            })?,
        };
        // Discovery waits out a time-out per absent node: Ctrl-C returns
        // at once (discovery ends on its own and drops the port).
        let sys = interrupt::abandon_on_interrupt(py, move || HostSnakeSystem::open(inner))?
            .map_err(|e| host_error(py, e))?;
        Ok(SnakeSystem {
            sys: Mutex::new(sys),
        })
    }

    /// The nodes, by ascending board ID.
    #[getter]
    fn nodes(&mut self) -> Vec<SnakeNode> {
        self.sys().nodes().iter().map(SnakeNode::from).collect()
    }

    /// Number of axes: seven per node.
    #[getter]
    fn axes(&mut self) -> usize {
        self.sys().nodes().len() * CHANNELS
    }

    /// Seconds on the port's clock.
    #[getter]
    fn now(&mut self) -> f64 {
        self.sys().port().now().as_secs_f64()
    }

    /// Let `seconds` pass (virtual time on the simulated bus), at most a
    /// day; Ctrl-C interrupts a long wait.
    fn wait(&mut self, py: Python<'_>, seconds: &Bound<'_, PyAny>) -> PyResult<()> {
        let d = crate::ports::wait_arg(seconds)?;
        let sys = self.sys();
        crate::ports::wait_on(py, sys.port_mut().as_mut(), d)
    }

    /// Find the nodes again (after a bus reset); buffers are kept.
    fn rescan(&mut self, py: Python<'_>) -> PyResult<()> {
        self.at_once(py, |s| s.rescan())
    }

    /// `LatchAllInputs`: one block read per node; True when every node
    /// answered (a node that missed has its inputs marked invalid).
    fn latch_all_inputs(&mut self, py: Python<'_>) -> bool {
        let sys = self.sys();
        py.detach(|| sys.latch_all_inputs().all_ok())
    }

    /// `ApplyAllOutputs`: per node, the buffered amplifier changes, then
    /// one block write of every channel set since the last apply; True
    /// when nothing failed in this cycle.
    fn apply_all_outputs(&mut self, py: Python<'_>) -> bool {
        let sys = self.sys();
        py.detach(|| sys.apply_all_outputs().all_ok())
    }

    /// One cycle (latch, then apply); True when nothing failed.
    fn cycle(&mut self, py: Python<'_>) -> bool {
        let sys = self.sys();
        py.detach(|| {
            sys.latch_all_inputs();
            sys.apply_all_outputs().all_ok()
        })
    }

    /// Encoder count relative to the midpoint preload, per axis (int32).
    fn encoder_counts<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray1<i32>> {
        self.per_axis(|n, ch| n.encoder_counts(ch)).into_pyarray(py)
    }

    /// `GetEncoderPosition`: the raw 24-bit count per axis (uint32).
    fn encoder_position<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray1<u32>> {
        self.per_axis(|n, ch| n.encoder_position(ch))
            .into_pyarray(py)
    }

    /// The encoder's overflow flag per axis (bool).
    fn encoder_overflow<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        self.per_axis(|n, ch| n.encoder_overflow(ch))
            .into_pyarray(py)
    }

    /// `GetEncoderVelocity`: the raw period, signed 768 kHz ticks (int16).
    fn encoder_period<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray1<i16>> {
        self.per_axis(|n, ch| n.encoder_period(ch)).into_pyarray(py)
    }

    /// Encoder velocity per axis, counts/s (float64; 0 when too slow).
    fn velocity<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.per_axis(|n, ch| n.encoder_velocity(ch))
            .into_pyarray(py)
    }

    /// `GetAnalogPosition`: the potentiometer, ADC + 8192 (uint16, 0..=16383).
    fn analog_position<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray1<u16>> {
        self.per_axis(|n, ch| n.analog_position(ch))
            .into_pyarray(py)
    }

    /// `GetMotorCurrent`: the current monitor, ADC + 8192 (uint16, 0..=16383).
    fn motor_current<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray1<u16>> {
        self.per_axis(|n, ch| n.motor_current(ch)).into_pyarray(py)
    }

    /// Amplifier on at the last latch, per axis (bool; False for a node
    /// that missed).
    fn amp_enabled<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        self.per_axis(|n, ch| Ok(n.is_valid() && n.amplifier_enabled(ch)?))
            .into_pyarray(py)
    }

    /// Amplifier fault line at the last latch, per axis (bool).
    fn amp_fault<'py>(&mut self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        self.per_axis(|n, ch| n.amplifier_fault(ch))
            .into_pyarray(py)
    }

    /// `SetMotorVoltage` for every axis (DAC codes 0..=65535, 32768 = 0 V)
    /// for the next apply; marks every channel valid.
    /// Any array of integers (numpy of any integer type, a list).
    fn set_dac(&mut self, py: Python<'_>, codes: &Bound<'_, PyAny>) -> PyResult<()> {
        let axes = self.axes();
        let codes = args::int_array(codes, "set_dac", axes)?
            .into_iter()
            .map(|v| {
                u16::try_from(v).map_err(|_| {
                    bad(
                        py,
                        format!("set_dac: DAC code {v} is out of range: it must be 0 to 65535"),
                    )
                })
            })
            .collect::<PyResult<Vec<u16>>>()?;
        let ids = self.board_ids(py, None)?;
        for (id, node_codes) in ids.into_iter().zip(codes.chunks(CHANNELS)) {
            let node = self.node_mut(py, id)?;
            for (ch, &c) in (1..=CHANNELS as u8).zip(node_codes) {
                node.set_motor_voltage(ch, c)
                    .map_err(|e| host_error(py, e))?;
            }
        }
        Ok(())
    }

    /// `SetMotorVoltage` of one channel (DAC code 0..=65535) for the next
    /// apply; marks the channel valid.
    fn set_motor_voltage(
        &mut self,
        py: Python<'_>,
        board: Arg<'_>,
        channel: Arg<'_>,
        code: Arg<'_>,
    ) -> PyResult<()> {
        let (b, ch, c) = (
            board_id(py, board)?,
            self::channel(py, channel)?,
            self::code(py, code, "motor DAC code")?,
        );
        self.node_mut(py, b)?
            .set_motor_voltage(ch, c)
            .map_err(|e| host_error(py, e))
    }

    /// The motor command the next apply writes to a channel (None: the
    /// channel is left alone).
    fn pending_motor_voltage(
        &mut self,
        py: Python<'_>,
        board: Arg<'_>,
        channel: Arg<'_>,
    ) -> PyResult<Option<u16>> {
        let (b, ch) = (board_id(py, board)?, self::channel(py, channel)?);
        Ok(self.node_mut(py, b)?.pending_motor_voltage(ch))
    }

    /// `SetMotorCurrent`: a channel's current limit (DAC code 0..=65535,
    /// 0 allows none), written at once.
    fn set_motor_current(
        &mut self,
        py: Python<'_>,
        board: Arg<'_>,
        channel: Arg<'_>,
        code: Arg<'_>,
    ) -> PyResult<()> {
        let (b, ch, c) = (
            board_id(py, board)?,
            self::channel(py, channel)?,
            self::code(py, code, "current limit code")?,
        );
        self.at_once(py, |s| s.set_motor_current(b, ch, c))
    }

    /// A channel's DAC as read back now: (motor command, current limit).
    fn dac(&mut self, py: Python<'_>, board: Arg<'_>, channel: Arg<'_>) -> PyResult<(u16, u16)> {
        let (b, ch) = (board_id(py, board)?, self::channel(py, channel)?);
        let d = self.at_once(py, |s| s.dac(b, ch))?;
        Ok((d.motor_voltage(), d.current_limit()))
    }

    /// Ask for one channel's amplifier on or off with the next apply.
    fn set_amplifier(
        &mut self,
        py: Python<'_>,
        board: Arg<'_>,
        channel: Arg<'_>,
        on: Arg<'_>,
    ) -> PyResult<()> {
        let (b, ch) = (board_id(py, board)?, self::channel(py, channel)?);
        let on = flag(on, "on")?;
        self.node_mut(py, b)?
            .set_amplifier_enable(ch, on)
            .map_err(|e| host_error(py, e))
    }

    /// Ask for every amplifier (of every node, or `board`) on or off with
    /// the next apply.
    #[pyo3(signature = (on, board=None))]
    fn set_amplifiers(
        &mut self,
        py: Python<'_>,
        on: Arg<'_>,
        board: Option<Arg<'_>>,
    ) -> PyResult<()> {
        let on = flag(on, "on")?;
        for id in self.board_ids(py, board)? {
            self.node_mut(py, id)?.set_all_amplifiers(on);
        }
        Ok(())
    }

    /// `SetPowerControl` at once: the amplifiers whose bit is set in
    /// `mask` (bit c-1 = channel c, 0..=127) take the matching bit of
    /// `enable`; the others keep theirs.
    fn set_power_control(
        &mut self,
        py: Python<'_>,
        board: Arg<'_>,
        mask: Arg<'_>,
        enable: Arg<'_>,
    ) -> PyResult<()> {
        let b = board_id(py, board)?;
        let mask: u8 = ranged(py, mask, 0, 0x7F, "power-control mask")?;
        let enable: u8 = ranged(py, enable, 0, 0x7F, "power-control enable")?;
        let control = PowerControl::default().with_mask(mask).with_enable(enable);
        self.at_once(py, |s| s.set_power_control(b, control))
    }

    /// `SetEncoderPreload`: the count a channel's encoder takes now
    /// (0..=0xFFFFFF; the overflow flag clears).
    fn set_encoder_preload(
        &mut self,
        py: Python<'_>,
        board: Arg<'_>,
        channel: Arg<'_>,
        count: Arg<'_>,
    ) -> PyResult<()> {
        let (b, ch) = (board_id(py, board)?, self::channel(py, channel)?);
        let count: u32 = ranged(py, count, 0, 0xFF_FFFF, "encoder preload")?;
        self.at_once(py, |s| s.set_encoder_preload(b, ch, count))
    }

    /// Reset a channel's encoder to the midpoint (0x800000), at once.
    fn reset_encoder(&mut self, py: Python<'_>, board: Arg<'_>, channel: Arg<'_>) -> PyResult<()> {
        let (b, ch) = (board_id(py, board)?, self::channel(py, channel)?);
        self.at_once(py, |s| s.reset_encoder(b, ch))
    }

    /// `GetDigitalPotWiper`: a channel's wiper, 0..=1023.
    fn digital_pot_wiper(
        &mut self,
        py: Python<'_>,
        board: Arg<'_>,
        channel: Arg<'_>,
    ) -> PyResult<u16> {
        let (b, ch) = (board_id(py, board)?, self::channel(py, channel)?);
        self.at_once(py, |s| s.digital_pot_wiper(b, ch))
            .map(Wiper::value)
    }

    /// `SetDigitalPotWiper`: 0..=1023 (375: the seed's nominal gain).
    fn set_digital_pot_wiper(
        &mut self,
        py: Python<'_>,
        board: Arg<'_>,
        channel: Arg<'_>,
        wiper: Arg<'_>,
    ) -> PyResult<()> {
        let (b, ch) = (board_id(py, board)?, self::channel(py, channel)?);
        let w: u16 = ranged(py, wiper, 0, 1023, "digital pot wiper")?;
        self.at_once(py, |s| s.set_digital_pot_wiper(b, ch, w))
    }

    /// The motor-current feedback gain a channel's wiper sets now (seed
    /// 001, eq. 1).
    fn feedback_gain(&mut self, py: Python<'_>, board: Arg<'_>, channel: Arg<'_>) -> PyResult<f64> {
        let (b, ch) = (board_id(py, board)?, self::channel(py, channel)?);
        self.at_once(py, |s| s.digital_pot_wiper(b, ch))
            .map(Wiper::feedback_gain)
    }

    /// The feedback gain wiper position `wiper` (0..=1023) sets.
    #[staticmethod]
    fn wiper_gain(py: Python<'_>, wiper: Arg<'_>) -> PyResult<f64> {
        let w: u16 = ranged(py, wiper, 0, 1023, "digital pot wiper")?;
        Wiper::new(w)
            .map(Wiper::feedback_gain)
            .map_err(|e| bad(py, e.to_string()))
    }

    /// `GetAnalogSwitches`: (speed_mode, o2); speed_mode False is torque
    /// control.
    fn analog_switches(
        &mut self,
        py: Python<'_>,
        board: Arg<'_>,
        channel: Arg<'_>,
    ) -> PyResult<(bool, bool)> {
        let (b, ch) = (board_id(py, board)?, self::channel(py, channel)?);
        self.at_once(py, |s| s.analog_switches(b, ch))
            .map(|o| (o.speed_mode, o.o2))
    }

    /// `SetAnalogSwitches`: speed (True) or torque (False) control, and
    /// the spare output O2.
    #[pyo3(signature = (board, channel, speed_mode, o2=None))]
    fn set_analog_switches(
        &mut self,
        py: Python<'_>,
        board: Arg<'_>,
        channel: Arg<'_>,
        speed_mode: Arg<'_>,
        o2: Option<Arg<'_>>,
    ) -> PyResult<()> {
        let (b, ch) = (board_id(py, board)?, self::channel(py, channel)?);
        let speed_mode = flag(speed_mode, "speed_mode")?;
        let o2 = o2.map_or(Ok(false), |o| flag(o, "o2"))?;
        let outputs = PotOutputs { speed_mode, o2 };
        self.at_once(py, |s| s.set_analog_switches(b, ch, outputs))
    }

    /// Whether a channel's EEPROM is write-protected.
    fn write_protect(
        &mut self,
        py: Python<'_>,
        board: Arg<'_>,
        channel: Arg<'_>,
    ) -> PyResult<bool> {
        let (b, ch) = (board_id(py, board)?, self::channel(py, channel)?);
        self.at_once(py, |s| s.write_protect(b, ch))
    }

    /// Set or clear a channel's EEPROM write protection.
    fn set_write_protect(
        &mut self,
        py: Python<'_>,
        board: Arg<'_>,
        channel: Arg<'_>,
        on: Arg<'_>,
    ) -> PyResult<()> {
        let (b, ch) = (board_id(py, board)?, self::channel(py, channel)?);
        let on = flag(on, "on")?;
        self.at_once(py, |s| s.set_write_protect(b, ch, on))
    }

    /// The seed's EEPROM index of (`channel` 1..=7, `word` 0..=13):
    /// channel in bits 7-4, word in bits 3-0.
    #[staticmethod]
    fn eeprom_index(py: Python<'_>, channel: Arg<'_>, word: Arg<'_>) -> PyResult<u32> {
        let ch = self::channel(py, channel)?;
        let word: u8 = ranged(py, word, 0, 13, "EEPROM word")?;
        EepromIndex::new(ch, word)
            .map(EepromIndex::index)
            .map_err(|e| host_error(py, e))
    }

    /// `GetEepromDataRaw`: the word at `index` (see `eeprom_index`).
    fn eeprom_raw(&mut self, py: Python<'_>, board: Arg<'_>, index: Arg<'_>) -> PyResult<u16> {
        let b = board_id(py, board)?;
        let index: u32 = ranged(py, index, 0, 0xFF, "EEPROM index")?;
        self.at_once(py, |s| s.eeprom_raw(b, index))
    }

    /// `SetEepromDataRaw`: write `value` (0..=65535) at `index`; a
    /// write-protected EEPROM raises `InvalidRequest`.
    fn set_eeprom_raw(
        &mut self,
        py: Python<'_>,
        board: Arg<'_>,
        index: Arg<'_>,
        value: Arg<'_>,
    ) -> PyResult<()> {
        let b = board_id(py, board)?;
        let index: u32 = ranged(py, index, 0, 0xFF, "EEPROM index")?;
        let value = code(py, value, "EEPROM value")?;
        self.at_once(py, |s| s.set_eeprom_raw(b, index, value))
    }

    /// `GetEepromDataFloat`: the float (32-bit) in words `index` and
    /// `index + 1` (the first word at most 12).
    fn eeprom_float(&mut self, py: Python<'_>, board: Arg<'_>, index: Arg<'_>) -> PyResult<f32> {
        let b = board_id(py, board)?;
        let index: u32 = ranged(py, index, 0, 0xFF, "EEPROM index")?;
        self.at_once(py, |s| s.eeprom_float(b, index))
    }

    /// `SetEepromDataFloat`: `value` stored as a 32-bit float in two words.
    fn set_eeprom_float(
        &mut self,
        py: Python<'_>,
        board: Arg<'_>,
        index: Arg<'_>,
        value: Arg<'_>,
    ) -> PyResult<()> {
        let b = board_id(py, board)?;
        let index: u32 = ranged(py, index, 0, 0xFF, "EEPROM index")?;
        let value = args::real(
            &value.0,
            "EEPROM float",
            Span::closed(f64::NEG_INFINITY, f64::INFINITY, ""),
        )?;
        let v = value as f32;
        if !v.is_finite() {
            return Err(bad(
                py,
                format!(
                    "EEPROM float {} is out of range: a 32-bit float is finite, at most about 3.4e38 in size",
                    firelink_wire::human::Number(value)
                ),
            ));
        }
        self.at_once(py, |s| s.set_eeprom_float(b, index, v))
    }

    /// One node's watchdog period, milliseconds (0: off).
    fn watchdog(&mut self, py: Python<'_>, board: Arg<'_>) -> PyResult<f64> {
        let b = board_id(py, board)?;
        self.at_once(py, |s| s.watchdog(b))
            .map(|d| d.as_secs_f64() * 1e3)
    }

    /// Program every node's watchdog: a period in milliseconds (one 5.208
    /// us tick to 341.32 ms) or `"off"` (with a warning). A node whose
    /// watchdog expires disables its amplifiers.
    fn set_watchdog(&mut self, py: Python<'_>, ms: Arg<'_>) -> PyResult<()> {
        let ms = &ms.0;
        let setting = crate::args::watchdog_setting(py, ms)?;
        if let Some(w) = setting.warning() {
            crate::errors::warn(py, w)?;
        }
        self.at_once(py, |s| s.set_watchdog(setting))
    }

    /// Per node, from the last latch: a dict with board_id, valid (the
    /// node answered), watchdog_expired, amp_enable and faults (bit c-1 =
    /// channel c) and timestamp (seconds between the last two latches).
    fn node_status<'py>(&mut self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        self.sys()
            .nodes()
            .iter()
            .map(|n| {
                let d = PyDict::new(py);
                let s = n.status();
                d.set_item("board_id", n.board_id())?;
                d.set_item("valid", n.is_valid())?;
                d.set_item("watchdog_expired", s.watchdog_timeout())?;
                d.set_item("amp_enable", s.amp_enable())?;
                d.set_item("faults", s.faults())?;
                d.set_item("timestamp", n.timestamp_seconds())?;
                Ok(d)
            })
            .collect()
    }

    /// Error counters since the system opened, as a dict (as `IoSystem.stats`).
    fn stats<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        stats_dict(py, self.sys().stats())
    }

    /// The last cycle: (every node answered, I/O time in microseconds).
    fn last_cycle(&mut self) -> (bool, f64) {
        cycle_result(self.sys().report())
    }

    fn __repr__(&mut self) -> String {
        let sys = self.sys();
        format!(
            "SnakeSystem(port={:?}, nodes={:?})",
            sys.port().name(),
            sys.nodes()
                .iter()
                .map(SnakeNodeIo::board_id)
                .collect::<Vec<_>>()
        )
    }
}

/// The Snake classes of the native module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<SnakeNode>()?;
    m.add_class::<SnakeSystem>()?;
    Ok(())
}
