"""Hostile arguments: every public function and method, given wrong types
and extreme values, raises one of the package's exceptions (never Python's
own TypeError, OverflowError or ValueError from a conversion, never a
crash, never a hang) and the objects it was called on stay usable.

Two sweeps per entry point: every argument in turn takes every hostile
value (the others at harmless defaults), then a seeded random mix of
hostile values in every argument at once. Values that are valid and would
only make the call long (a wait of 65535 s, a demo of 2.5 s) are left out:
what they do is the bounds tests' business. A call with the wrong number of
arguments is Python's TypeError, as for any function, and is not swept.
"""

from __future__ import annotations

import faulthandler
import math
import numbers
import random
import warnings
from pathlib import Path
from typing import Any, Callable, Optional

import numpy as np
import pytest

import firelink

CONFIGS = Path(__file__).resolve().parents[2] / "configs"
ONE_BOARD = str(CONFIGS / "bench-1board.json")

HOSTILE: list[Any] = [
    None, True, False, -1, 0, 1, 7, 63, 64, 65535, 65536, 2**31, 2**32, 2**48, 2**63, 2**64, 2**70,
    -(2**63) - 1, 2**5000, math.nan, math.inf, -math.inf, -0.0, 1e-300, 1e-9, 0.5, 1e300,
    np.int64(3), np.uint64(2**64 - 1), np.float32(2.5), np.bool_(True), np.float64(math.nan),
    "", "sim", "off", "x", "8", "udp:", "udp:127.0.0.1:0", "\x00", "é", "9" * 400,
    b"", b"\xff" * 9000, bytearray(4), memoryview(b"abcd"), [], [1, 2], ["sim"], [[1]], {}, (), {"a": 1},
    object(), print, iter([1, 2]), np.zeros(0), np.zeros(3), np.full(32, 1e9), np.zeros((2, 2)),
    np.array(["a", "b"]), np.array([1 + 2j]), np.zeros(4, dtype=np.int8), np.zeros(42, dtype=np.uint64),
]


def shown(v: Any) -> str:
    """A value for a failure message (repr of 2**5000 raises in 3.11+)."""
    try:
        text = repr(v)
    except ValueError:
        return f"<int of {v.bit_length()} bits>"
    return text if len(text) < 60 else text[:57] + "..."


def number(v: Any) -> Optional[float]:
    """`v` as a float when it is a plain number (not a bool), else None."""
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Real):
        return None
    try:
        return float(v)
    except OverflowError:
        return math.inf


def long_if_above(limit: float) -> Callable[[Any], bool]:
    """A value that, if valid, makes the call run long: a number above `limit`
    (and at most the largest any call accepts)."""

    def skip(v: Any) -> bool:
        x = number(v)
        return x is not None and limit < x <= 1e9

    return skip


class Sweep:
    """Calls that may only return or raise the package's exceptions."""

    def __init__(self) -> None:
        self.failures: list[str] = []
        self.calls = 0

    def call(self, label: str, f: Callable[..., Any], kwargs: dict[str, Any]) -> None:
        self.calls += 1
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)  # "watchdogs are OFF", on purpose
                f(**kwargs)
        except firelink.FirelinkError as e:
            message = str(e)
            if not message or "\n" in message:
                self.failures.append(f"{label}: unreadable message {message!r}")
        except Exception as e:  # noqa: BLE001 - the point: nothing else may come out
            args = ", ".join(f"{k}={shown(v)}" for k, v in kwargs.items())
            self.failures.append(f"{label}({args}): {type(e).__name__}: {e}")

    def each_argument(self, label: str, f: Callable[..., Any], defaults: dict[str, Any],
                      skip: Optional[dict[str, Callable[[Any], bool]]] = None) -> None:
        skip = skip or {}
        for name in defaults:
            for v in HOSTILE:
                if name in skip and skip[name](v):
                    continue
                self.call(label, f, {**defaults, name: v})

    def mixed(self, label: str, f: Callable[..., Any], defaults: dict[str, Any],
              skip: Optional[dict[str, Callable[[Any], bool]]] = None, rounds: int = 25,
              seed: int = 7) -> None:
        skip = skip or {}
        rng = random.Random(f"{seed}:{label}")
        for _ in range(rounds):
            kwargs = {}
            for name, default in defaults.items():
                v = rng.choice(HOSTILE + [default])
                kwargs[name] = default if name in skip and skip[name](v) else v
            self.call(label, f, kwargs)

    def check(self) -> None:
        assert not self.failures, f"{len(self.failures)} of {self.calls} calls:\n" + "\n".join(self.failures[:40])


@pytest.fixture
def sweep():
    # A hang shows where it hangs instead of stalling the suite.
    faulthandler.dump_traceback_later(900, exit=True)
    s = Sweep()
    yield s
    faulthandler.cancel_dump_traceback_later()
    s.check()


WAIT = {"seconds": long_if_above(0.05)}


def test_ports_and_their_methods(sweep):
    port = firelink.open("sim:2")
    sweep.each_argument("open", firelink.open, {"port": "sim:1"})
    sweep.each_argument("Port", firelink.Port, {"spec": "sim:1"})
    sweep.each_argument("Port.wait", port.wait, {"seconds": 0.001}, WAIT)
    for name, f, defaults in [
        ("read_quadlet", port.read_quadlet, {"node": 0, "address": 4}),
        ("write_quadlet", port.write_quadlet, {"node": 0, "address": 3, "value": 100}),
        ("read_block", port.read_block, {"node": 0, "address": 0, "quadlets": 4}),
        ("write_block", port.write_block, {"node": 0, "address": 0x1000, "data": b"\0\0\0\0"}),
    ]:
        sweep.each_argument(f"Port.{name}", f, defaults)
        sweep.mixed(f"Port.{name}", f, defaults)
    assert len(port.scan()) == 2


def test_io_systems_and_their_methods(sweep):
    sweep.each_argument("IoSystem", firelink.IoSystem, {"port": "sim:1", "protocol": None})
    io = firelink.IoSystem("sim:2")
    axes = io.axes
    for name, f, defaults, skip in [
        ("wait", io.wait, {"seconds": 0.001}, WAIT),
        ("run_cycles", io.run_cycles, {"cycles": 2}, {"cycles": long_if_above(100)}),
        ("set_dac", io.set_dac, {"bits": np.full(axes, 0x8000)}, None),
        ("set_current", io.set_current, {"amps": np.zeros(axes)}, None),
        ("set_power", io.set_power, {"on": False, "board": None}, None),
        ("set_relay", io.set_relay, {"on": False, "board": None}, None),
        ("set_amplifiers", io.set_amplifiers, {"on": False, "board": None}, None),
        ("set_watchdog", io.set_watchdog, {"ms": 20}, None),
        ("read_register", io.read_register, {"board_id": 0, "offset": 4}, None),
        ("write_register", io.write_register, {"board_id": 0, "offset": 3, "value": 1}, None),
    ]:
        sweep.each_argument(f"IoSystem.{name}", f, defaults, skip)
        sweep.mixed(f"IoSystem.{name}", f, defaults, skip)
    assert io.cycle() in (True, False)
    assert io.read_all()
    assert len(io.encoder_counts()) == axes


def test_snake_systems_and_their_methods(sweep):
    sweep.each_argument("SnakeSystem", firelink.SnakeSystem, {"port": "sim", "config": None})
    s = firelink.SnakeSystem("sim")
    board_channel = {"board": 1, "channel": 2}
    for name, defaults in [
        ("wait", {"seconds": 0.001}),
        ("set_dac", {"codes": np.full(s.axes, 0x8000)}),
        ("set_motor_voltage", {**board_channel, "code": 0x8000}),
        ("pending_motor_voltage", board_channel),
        ("set_motor_current", {**board_channel, "code": 100}),
        ("dac", board_channel),
        ("set_amplifier", {**board_channel, "on": False}),
        ("set_amplifiers", {"on": False, "board": None}),
        ("set_power_control", {"board": 1, "mask": 0, "enable": 0}),
        ("set_encoder_preload", {**board_channel, "count": 0x800000}),
        ("reset_encoder", board_channel),
        ("digital_pot_wiper", board_channel),
        ("set_digital_pot_wiper", {**board_channel, "wiper": 375}),
        ("feedback_gain", board_channel),
        ("wiper_gain", {"wiper": 375}),
        ("analog_switches", board_channel),
        ("set_analog_switches", {**board_channel, "speed_mode": False, "o2": False}),
        ("write_protect", board_channel),
        ("set_write_protect", {**board_channel, "on": True}),
        ("eeprom_index", {"channel": 1, "word": 0}),
        ("eeprom_raw", {"board": 1, "index": 0x10}),
        ("set_eeprom_raw", {"board": 1, "index": 0x10, "value": 1}),
        ("eeprom_float", {"board": 1, "index": 0x10}),
        ("set_eeprom_float", {"board": 1, "index": 0x10, "value": 1.5}),
        ("watchdog", {"board": 1}),
        ("set_watchdog", {"ms": 20}),
    ]:
        f = getattr(s, name)
        skip = WAIT if name == "wait" else None
        sweep.each_argument(f"SnakeSystem.{name}", f, defaults, skip)
        sweep.mixed(f"SnakeSystem.{name}", f, defaults, skip)
    assert s.cycle() in (True, False)
    assert len(s.nodes) == 6


def test_the_emulator(sweep, udp_timeout):
    def start(**kw: Any) -> None:
        firelink.Emulator(**kw).stop()

    defaults = {"boards": 1, "firmware": "8", "robot": "qla", "config": None}
    sweep.each_argument("Emulator", start, defaults)
    sweep.mixed("Emulator", start, defaults)
    with firelink.Emulator(boards=1) as emu:
        sweep.each_argument("Emulator.port", emu.port, {"timeout": udp_timeout})
        assert len(emu.port(timeout=udp_timeout).scan()) == 1


def test_configurations_and_packets(sweep):
    sweep.each_argument("load_config", firelink.load_config, {"path": ONE_BOARD})
    sweep.each_argument("parse_config", firelink.parse_config, {"text": "{}", "file": "x.json"})
    sweep.each_argument("decode_packet", firelink.decode_packet, {"data": b"\0" * 16, "bridge": False})
    sweep.each_argument("encode_packet", firelink.encode_packet, {"fields": None, "bridge": False})
    fields = {"tcode_name": "read_request_quadlet", "destination_id": 0xFFC0, "offset": 0}
    for key in ["tcode_name", "destination_id", "offset", "tl", "generation", "quadlet_data"]:
        sweep.each_argument(f"encode_packet[{key}]", lambda **kw: firelink.encode_packet({**fields, **kw}),
                            {key: fields.get(key, 0)})
    sweep.each_argument("crc1394", firelink.crc1394, {"data": b"abcd"})


def test_the_demo_and_the_benchmark(sweep):
    defaults = {
        "port": "sim", "duration": 0.01, "rate": 1000.0, "protocol": "broadcast", "firmware": "8",
        "fault": "none", "pacing": None, "watchdog_ms": 20.0, "config": ONE_BOARD,
    }

    def demo(**kw: Any) -> None:
        firelink.run_demo(kw.pop("port"), **kw)

    skip = {"duration": long_if_above(0.05), "rate": long_if_above(2000)}
    sweep.each_argument("run_demo", demo, defaults, skip)
    sweep.mixed("run_demo", demo, defaults, skip, rounds=15)
    # A valid benchmark takes seconds (it also times the 28-axis cycle):
    # each sweep keeps one argument refused that is checked after the swept
    # one (no transport; an unknown firmware), so none runs.
    bench = {"transports": [], "boards": [1], "protocols": ["broadcast"], "cycles": 3, "firmware": "8",
             "plot": None}
    # A string is a valid plot path: the sweep must not write files here.
    no_files = {"plot": lambda v: isinstance(v, str), "transports": lambda v: True}
    sweep.each_argument("run_bench", lambda **kw: firelink.run_bench(**kw), bench, no_files)
    sweep.each_argument("run_bench", lambda **kw: firelink.run_bench(**kw),
                        {"transports": ["sim"], "firmware": "9"}, {"firmware": lambda v: True})


def test_arrays_of_any_numeric_kind_are_converted_or_refused_with_the_reason():
    io = firelink.IoSystem("sim:1")
    for dtype in (np.int8, np.int16, np.int32, np.int64, np.uint16, np.uint32, np.uint64):
        io.set_dac(np.full(4, 0x1000, dtype=dtype) if np.iinfo(dtype).max >= 0x1000 else np.full(4, 100, dtype=dtype))
    io.set_dac([0x8000, 0x8001, 0x8002, 0x8003])
    assert list(io.dac()) == [0x8000, 0x8001, 0x8002, 0x8003]
    io.set_dac(np.arange(8, dtype=np.int64)[::2])  # not contiguous: copied
    assert list(io.dac()) == [0, 2, 4, 6]
    for amps in (np.zeros(4, dtype=np.float32), np.array([1, 0, 0, 0]), [0.5, 0, 0, 0], (0, 0, 0, 0)):
        io.set_current(amps)
    with pytest.raises(firelink.InvalidRequest, match="integers, not float64"):
        io.set_dac(np.zeros(4))
    with pytest.raises(firelink.InvalidRequest, match="shape"):
        io.set_dac(np.zeros((2, 2), dtype=np.int64))
    with pytest.raises(firelink.InvalidRequest, match="not bool"):
        io.set_current(np.zeros(4, dtype=bool))
    with pytest.raises(firelink.InvalidRequest, match="out of range"):
        io.set_dac(np.full(4, 2**64 - 1, dtype=np.uint64))
    with pytest.raises(firelink.InvalidRequest, match="array of 4"):
        io.set_current("0000")


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda io: io.set_power(True, board=-1), "board ID -1 is out of range"),
        (lambda io: io.set_power(True, board=2**70), "board ID 1180591620717411303424 is out of range"),
        (lambda io: io.set_power("off"), "on must be True or False, not str"),
        (lambda io: io.read_register(0, 2**5000), r"address \(an integer of 5001 bits\) is out of range"),
        (lambda io: io.wait(1e300), "wait 1e300 s is out of range"),
        (lambda io: io.wait(float("nan")), "wait is NaN"),
        (lambda io: io.run_cycles(10**10), "cycles 10000000000 is out of range: it must be 0 to 1000000000"),
        (lambda io: io.run_cycles(2.0), "cycles must be an integer"),
        (lambda io: io.write_register(0, 3, -1), "value -1 is out of range: it must be 0 to 0xFFFFFFFF"),
    ],
)
def test_messages_name_the_argument_the_value_and_the_range(call, match):
    io = firelink.IoSystem("sim:1")
    with pytest.raises(firelink.InvalidRequest, match=match):
        call(io)
