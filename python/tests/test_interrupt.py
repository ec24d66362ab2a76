"""Ctrl-C: a long call ends with KeyboardInterrupt, and a robot it powered
is powered down first.

Each test runs the call in a child Python whose watcher thread prints
"started" once the main thread is in the call (the line marked "# the long
call"; the call releases the GIL, so the watcher runs), sends SIGINT and
waits (a generous bound, never a tight one) for the child to end. The
traceback must end inside the call: an interrupt that landed before it
would prove nothing.
"""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path
from typing import Callable, Optional

import pytest

import firelink

ONE_BOARD = str(Path(__file__).resolve().parents[2] / "configs" / "bench-1board.json")

#: How long a child may take to start, and to end after SIGINT.
BOUND_S = 60.0

#: STATUS register (quadlet 0) bits: motor power enabled, amplifiers on.
POWER_ENABLED = 1 << 18
AMPLIFIERS = 0xF

#: Put before each child's code: print "started" once the main thread runs
#: the line marked "# the long call".
PRELUDE = """
import signal, sys, threading, time

# A shell that starts the test run in the background (`cmd &`, nohup, CI
# runners) leaves SIGINT ignored, and Python then installs no
# KeyboardInterrupt for it: give the child the handler a terminal gives.
signal.signal(signal.SIGINT, signal.default_int_handler)

def _announce():
    script = __file__
    line = next(i for i, text in enumerate(open(script), 1) if text.rstrip().endswith("# the long call"))
    main = threading.main_thread().ident
    while True:
        frame = sys._current_frames().get(main)
        while frame is not None and frame.f_code.co_filename != script:
            frame = frame.f_back
        if frame is not None and frame.f_lineno == line:
            print("started", flush=True)
            return
        time.sleep(0.01)

threading.Thread(target=_announce, daemon=True).start()
"""

pytestmark = pytest.mark.skipif(not hasattr(signal, "SIGINT") or os.name != "posix",
                                reason="POSIX signals")


def start(code: str, *args: str, tmp: Path) -> subprocess.Popen[str]:
    """A child running `code` from a file (its traceback shows the lines);
    returns once the child is in its long call."""
    script = tmp / "child.py"
    script.write_text(PRELUDE + textwrap.dedent(code))
    child = subprocess.Popen(
        [sys.executable, str(script), *args],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    assert child.stdout is not None
    ready, _, _ = select.select([child.stdout], [], [], BOUND_S)
    assert ready, "the child did not start"
    line = child.stdout.readline()
    if line.strip() != "started":
        child.kill()
        pytest.fail(f"the child did not start: {line!r} {child.communicate()}")
    return child


def interrupt(child: subprocess.Popen[str], inside: str,
              running: Optional[Callable[[], bool]] = None) -> str:
    """Send SIGINT once `running()` says the call got going (by default: it
    is in it), wait for the child to end; its stderr. The traceback names
    `inside`."""
    deadline = time.monotonic() + BOUND_S
    if running is not None:
        while not running():
            assert child.poll() is None, child.communicate()
            assert time.monotonic() < deadline, "the call never got going"
            time.sleep(0.05)
    assert child.poll() is None, child.communicate()
    child.send_signal(signal.SIGINT)
    try:
        _, err = child.communicate(timeout=BOUND_S)
    except subprocess.TimeoutExpired:
        child.kill()
        pytest.fail("SIGINT did not end the call")
    assert child.returncode != 0
    assert "KeyboardInterrupt" in err, err
    assert inside in err, err
    return err


@pytest.mark.parametrize(
    "code, inside",
    [
        ("""
         import firelink
         firelink.run_demo(port="sim", duration=600)  # the long call
         """, "run_demo_json"),
        ("""
         import firelink
         io = firelink.IoSystem("sim:2")
         io.run_cycles(10**9)  # the long call
         """, "io.run_cycles"),
        ("""
         import firelink
         port = firelink.open("udp:127.0.0.1:9")  # a UDP port waits in real time; no traffic
         port.wait(86400)  # the long call
         """, "port.wait"),
        ("""
         import firelink
         firelink.run_bench(transports=["sim"], boards=[1], protocols=["broadcast"], cycles=10**6)  # the long call
         """, "run_bench_json"),
    ],
    ids=["run_demo", "run_cycles", "wait", "run_bench"],
)
def test_ctrl_c_ends_a_long_call(code, inside, tmp_path):
    interrupt(start(code, tmp=tmp_path), inside)


def test_ctrl_c_powers_down_the_boards_the_demo_powered(udp_timeout, tmp_path):
    """The demo against boards in this process (over loopback UDP), their
    watchdogs off: only the demo's own power-down can turn them off."""
    code = """
        import sys, warnings
        import firelink
        warnings.simplefilter("ignore")  # the watchdog is off on purpose
        firelink.run_demo(port=sys.argv[1], duration=600, rate=500, watchdog_ms="off", config=sys.argv[2], timeout=0.25)  # the long call
        """
    with firelink.Emulator(boards=1) as emu:
        port = emu.port(timeout=udp_timeout)
        node = port.scan()[0].node

        def status() -> int:
            return port.read_quadlet(node, 0)

        assert status() & (POWER_ENABLED | AMPLIFIERS) == 0
        child = start(code, emu.address, ONE_BOARD, tmp=tmp_path)

        def powered() -> bool:
            return status() & POWER_ENABLED != 0 and status() & AMPLIFIERS != 0

        interrupt(child, "run_demo_json", running=powered)
        after = status()
    assert after & POWER_ENABLED == 0, hex(after)
    assert after & AMPLIFIERS == 0, hex(after)
