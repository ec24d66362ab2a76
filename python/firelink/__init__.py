"""Firelink from Python: real-time robot control over IEEE 1394 / UDP.

The package sits on the Rust library: the host library (ports, discovery,
the I/O protocols, register access), the testbed (emulated boards on the
simulated bus, the in-process emulator, the demo and the benchmark) and the
configuration loader. Calls that do I/O or simulation release the GIL;
long ones (the demo, the benchmark, ``run_cycles``, long waits, opening an
``IoSystem`` or ``SnakeSystem``) end
with ``KeyboardInterrupt`` on Ctrl-C, the demo powering down the boards it
powered. Every argument is checked: a wrong type or an out-of-range value
raises ``InvalidRequest`` (``PortError`` for ports and firmware,
``ConfigError``, ``PacketError``) saying what was given and what is
allowed; a call with a missing or unknown argument is Python's own
``TypeError``, as for any function.

Quick start::

    import firelink
    io = firelink.IoSystem("sim")          # 8 emulated QLA boards, simulated bus
    io.read_all(); print(io.encoder_counts())
    with firelink.Emulator(boards=4) as emu:
        port = firelink.open(emu.address)
        print(port.scan())

Seed 001's Snake nodes (seven channels each, the seed's Get/Set list)::

    snake = firelink.SnakeSystem("sim")    # the six nodes of configs/snake-seed001.json
    snake.latch_all_inputs(); snake.analog_position()
    snake.set_digital_pot_wiper(0, 1, 375); snake.apply_all_outputs()

Port descriptions, as every Firelink front end reads them
(``firelink.parse_port`` writes one back): ``"sim"`` (the robot's emulated
boards on the simulated bus; for ``open``, ``Port`` and ``IoSystem``, seed
000's dVRK: 8 QLA1 boards at firmware Rev 8), ``"sim:N"`` or ``"sim:N:FW"``
(boards 0..N of it, N 1..16, FW 7, 8, 9 or seed), ``"emulate"`` (the same
boards behind an in-process emulator; ``run_demo`` only),
``"udp:HOST[:PORT]"`` (a running ``firelink emulate`` or a real bridge
board), ``"fw"`` or ``"fw:CARD"`` (a FireWire card through Linux /dev/fw*,
or the emulated boards under ``firelink fw-run``).
"""

from __future__ import annotations

import datetime
import json
import operator
from collections.abc import Iterable, Iterator, Mapping
from os import PathLike
from typing import Any, Optional, Union

from . import _firelink
from ._errors import (
    BusError,
    BusTimeout,
    ConfigError,
    EmulatorClosed,
    FirelinkError,
    InvalidRequest,
    NoBoardsError,
    PacketError,
    PortError,
)
from ._firelink import (
    Board,
    Config,
    Emulator,
    IoSystem,
    Port,
    SnakeNode,
    SnakeSystem,
    crc1394,
    load_config,
    parse_config,
    parse_port,
)

__all__ = [
    "Board",
    "BusError",
    "BusTimeout",
    "Config",
    "ConfigError",
    "Emulator",
    "EmulatorClosed",
    "FirelinkError",
    "InvalidRequest",
    "IoSystem",
    "NoBoardsError",
    "PacketError",
    "Port",
    "PortError",
    "Report",
    "SnakeNode",
    "SnakeSystem",
    "crc1394",
    "decode_packet",
    "encode_packet",
    "load_config",
    "open",
    "parse_config",
    "parse_port",
    "run_bench",
    "run_demo",
]


def open(port: str) -> Port:  # noqa: A001 - the natural name, as in io.open
    """Open a port from its description (see the module docstring); a
    description that is not a string, or names no port, raises
    ``PortError``."""
    if not isinstance(port, str):
        raise PortError(f"a port description is a string, not {type(port).__name__}")
    return Port(port)


class Report(Mapping[str, Any]):
    """A typed report (demo or benchmark): read-only, attribute access
    (``report.errors.total``) and mapping access (``report["errors"]``);
    ``to_dict()`` gives plain dicts and lists, ``to_json()`` the same JSON
    as the command line's ``--json``."""

    __slots__ = ("_data",)

    def __init__(self, data: Mapping[str, Any]) -> None:
        object.__setattr__(self, "_data", dict(data))

    @staticmethod
    def _wrap(value: Any) -> Any:
        if isinstance(value, dict):
            return Report(value)
        if isinstance(value, list):
            return [Report._wrap(v) for v in value]
        return value

    def __getattr__(self, name: str) -> Any:
        try:
            return Report._wrap(self._data[name])
        except KeyError:
            raise AttributeError(name) from None

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError("a Report is read-only")

    def __getitem__(self, key: str) -> Any:
        return Report._wrap(self._data[key])

    def __iter__(self) -> Iterator[str]:
        return iter(self._data)

    def __len__(self) -> int:
        return len(self._data)

    def __repr__(self) -> str:
        keys = ", ".join(list(self._data)[:6])
        return f"Report({keys}{', ...' if len(self._data) > 6 else ''})"

    def to_dict(self) -> dict[str, Any]:
        """The report as plain dicts and lists."""
        return json.loads(json.dumps(self._data))

    def to_json(self) -> str:
        """The report as JSON text."""
        return json.dumps(self._data)


class _RateNotGiven(float):
    """``run_demo``'s default ``rate``: 6000 Hz unless ``period`` is given."""

    def __repr__(self) -> str:
        return "6000.0"


_RATE_NOT_GIVEN = _RateNotGiven(6000.0)


def run_demo(
    port: str = "sim",
    *,
    duration: float = 3.0,
    period: Union[str, float, datetime.timedelta, None] = None,
    rate: float = _RATE_NOT_GIVEN,
    protocol: str = "broadcast",
    firmware: Union[str, int] = "8",
    fault: str = "none",
    pacing: Optional[str] = None,
    watchdog_ms: Union[float, str] = 20.0,
    config: Optional[Union[Config, str, PathLike[str]]] = None,
    timeout: Optional[float] = None,
    detail: str = "fast",
) -> Report:
    """Run the demo (``firelink demo``) and return its report.

    ``port``: ``sim``, ``emulate`` or ``udp:HOST[:PORT]``; ``duration``:
    seconds of motion, above 0 and at most 86400; ``period``: the servo
    period, 10 us to 1 s (100 kHz to 1 Hz), as on the command line's
    ``--period`` (a string with its unit: ``"1ms"``, ``"250us"``,
    ``"6kHz"``), or a number of seconds as ``time.sleep`` takes
    (``0.001``), or a ``datetime.timedelta`` (default: 6 kHz);
    ``rate``: the older spelling, the period as a rate in Hz, 1 to 100000
    (``rate=1000`` is ``period="1ms"``; giving both is refused); ``fault``: ``none``, ``stop-host``, ``corrupt-query``,
    ``board-loss`` or ``following-error``; ``watchdog_ms``: 0.00521 to
    341.32 ms, or ``"off"`` (with a ``UserWarning``); ``config``: a
    ``Config`` or a configuration file (default: seed 000's dVRK);
    ``timeout``: over UDP (``emulate``, ``udp:``), seconds a read waits
    for its answer, above 0 and at most 60 (default 0.02, the command
    line's ``--timeout-ms 20``: in a servo cycle a later answer is a
    missed board, a fault); ``detail``: on ``sim``, the simulated bus's
    level of detail, ``"fast"`` (a packet's deliveries in one batch where
    that is exact) or ``"packet"`` (every delivery an event of its own),
    the same answer either way (``report["detail"]`` counts which ran).
    ``report.verdict`` is ``"ok"`` or says what went wrong. Ctrl-C stops
    the robot at its next cycle, powers down the boards it powered and
    raises ``KeyboardInterrupt``.
    """
    if isinstance(period, datetime.timedelta):
        period = period.total_seconds()
    rate_given = rate is not _RATE_NOT_GIVEN
    text = _firelink.run_demo_json(
        port, duration, period, rate, rate_given, protocol, firmware, fault, pacing, watchdog_ms, config, timeout,
        detail,
    )
    return Report(json.loads(text))


def run_bench(
    *,
    transports: Union[str, Iterable[str]] = ("sim", "udp"),
    boards: Iterable[int] = (2, 4, 8, 16, 32, 62),
    protocols: Union[str, Iterable[str]] = ("sequential", "broadcast"),
    cycles: int = 1000,
    firmware: Union[str, int] = "8",
    plot: Optional[Union[str, PathLike[str]]] = None,
) -> Report:
    """Run the benchmark of seed 000's Fig. 11 (``firelink bench``); with
    ``plot``, also draw the figure into that PNG file.

    ``transports``: ``sim`` and/or ``udp``; ``boards``: counts 1 to 62
    (above 16: modelled from a measured count before it), at most 64 of
    them; ``cycles``: per point, 1 to 1000000. Ctrl-C raises
    ``KeyboardInterrupt`` at once (the benchmark, on emulated boards only,
    finishes its current work in a background thread).
    """
    text = _firelink.run_bench_json(transports, boards, protocols, cycles, firmware, plot)
    return Report(json.loads(text))


def decode_packet(data: bytes, *, bridge: bool = False) -> dict[str, Any]:
    """Decode one IEEE 1394 packet (with ``bridge``, a host-to-bridge
    datagram) into its fields; raises ``PacketError`` naming what is wrong."""
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise PacketError(f"decode_packet takes bytes, not {type(data).__name__}")
    return json.loads(_firelink.decode_packet_json(bytes(data), bridge))


def encode_packet(fields: Optional[Mapping[str, Any]] = None, *, bridge: bool = False, **kw: Any) -> bytes:
    """Build a packet from its fields (the keys ``decode_packet`` gives, as a
    mapping and/or keywords); raises ``PacketError`` naming a missing or
    out-of-range field."""
    if fields is None:
        merged: dict[Any, Any] = {}
    elif isinstance(fields, Mapping):
        merged = dict(fields)
    else:
        raise PacketError(f"encode_packet takes a mapping of fields, not {type(fields).__name__}")
    merged.update(kw)
    for key in ("header_crc_ok", "data_crc_ok", "packet_length"):
        merged.pop(key, None)
    try:
        # Integers of any kind (numpy's too) become JSON numbers; NaN and
        # other objects are refused here.
        text = json.dumps(merged, allow_nan=False, default=operator.index)
    except (TypeError, ValueError, RecursionError) as e:
        raise PacketError(f"packet fields must be integers and strings: {e}") from None
    return _firelink.encode_packet_json(text, bridge)
