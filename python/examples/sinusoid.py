"""Run a sinusoid on one joint and plot setpoint against position.

By default against an in-process emulator over loopback UDP, paced by the
wall clock at 1 kHz; ``--port sim`` runs on the simulated bus in virtual
time instead. The controller is a PD loop (with the setpoint's velocity fed forward) on the motor current of board 0,
axis 0, written in Python with numpy. Saves ``sinusoid.png`` (matplotlib).

    python examples/sinusoid.py [--port emulate|sim] [--seconds 3] [--out sinusoid.png]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import firelink

RATE_HZ = 1000.0
AMPLITUDE = 2000.0  # encoder counts
FREQUENCY = 1.0  # Hz
KP = 9.6e-4  # A per count: about 10 Hz closed-loop bandwidth for this motor
KD = 2.1e-5  # A per count/s
LIMIT = 1.0  # A


def power_up(io: firelink.IoSystem, step) -> None:
    io.set_watchdog(20)
    io.set_relay(True)
    io.set_power(True)
    for _ in range(300):
        step()
    io.set_amplifiers(True, board=0)
    for _ in range(30):
        step()
    if not io.amp_enabled()[0]:
        raise SystemExit("amplifier did not come on")


def run(io: firelink.IoSystem, seconds: float, virtual: bool):
    period = 1.0 / RATE_HZ
    deadline = time.perf_counter()

    def pace() -> None:
        """Wait out the rest of the period: virtual time on the simulated
        bus, the wall clock against the emulator."""
        nonlocal deadline
        if virtual:
            io.wait(period)
            return
        deadline += period
        delay = deadline - time.perf_counter()
        if delay > 0:
            time.sleep(delay)

    def step() -> None:
        io.read_all()
        io.write_all()
        pace()

    power_up(io, step)
    command = np.zeros(io.axes)
    start = float(io.encoder_counts()[0])
    n = int(seconds * RATE_HZ)
    t = np.arange(n) * period
    setpoint = start + AMPLITUDE * np.sin(2 * np.pi * FREQUENCY * t)
    setpoint_velocity = 2 * np.pi * FREQUENCY * AMPLITUDE * np.cos(2 * np.pi * FREQUENCY * t)
    position = np.empty(n)
    previous = start
    for k in range(n):
        io.read_all()
        here = float(io.encoder_counts()[0])
        velocity = (here - previous) * RATE_HZ
        previous = here
        position[k] = here
        command[0] = np.clip(KP * (setpoint[k] - here) + KD * (setpoint_velocity[k] - velocity), -LIMIT, LIMIT)
        io.set_current(command)
        io.write_all()
        pace()
    io.set_amplifiers(False)
    io.set_power(False)
    io.cycle()
    return t, setpoint - start, position - start, io.stats()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--port", choices=["emulate", "sim"], default="emulate")
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--out", default="sinusoid.png")
    args = parser.parse_args()
    if args.port == "sim":
        t, sp, pos, stats = run(firelink.IoSystem("sim:1"), args.seconds, virtual=True)
    else:
        with firelink.Emulator(boards=1) as emu:
            t, sp, pos, stats = run(firelink.IoSystem(emu.port()), args.seconds, virtual=False)
    error = sp - pos
    tail = error[len(error) // 3 :]
    rms = float(np.sqrt(np.mean(tail**2)))
    print(f"{len(t)} cycles on {args.port}, I/O errors {stats['total_errors']}, "
          f"tracking error RMS {rms:.0f} counts of {AMPLITUDE:.0f}")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(9, 6), height_ratios=[3, 1])
    top.plot(t, sp, label="setpoint", linewidth=2)
    top.plot(t, pos, label="position (encoder)", linestyle="--")
    top.set_ylabel("joint position, encoder counts")
    top.set_title(f"Board 0 axis 0: {FREQUENCY:g} Hz sinusoid, PD current loop in Python at {RATE_HZ:.0f} Hz ({args.port})")
    top.legend(loc="upper right")
    top.grid(True, alpha=0.3)
    bottom.plot(t, error, color="tab:red")
    bottom.set_ylabel("error, counts")
    bottom.set_xlabel("time, s")
    bottom.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(args.out, dpi=100)
    print(f"wrote {args.out}")
    if stats["total_errors"] != 0 or rms > 0.2 * AMPLITUDE:
        raise SystemExit("tracking failed")


if __name__ == "__main__":
    main()
