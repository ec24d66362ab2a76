"""Python overhead per I/O cycle: ``read_all()`` + ``write_all()`` called
from Python against the same cycles run in a Rust loop (``run_cycles``),
side by side in one process, interleaved, medians of several rounds.

    python bench/overhead.py [--port sim|udp:HOST[:PORT]] [--cycles 2000] [--rounds 7]

Build the package in release mode first (``maturin develop --release``);
the figures go to BENCHMARKS.md.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

import firelink


def python_loop(io: firelink.IoSystem, n: int) -> float:
    start = time.perf_counter()
    for _ in range(n):
        io.read_all()
        io.write_all()
    return time.perf_counter() - start


def python_loop_with_arrays(io: firelink.IoSystem, n: int) -> float:
    command = np.zeros(io.axes)
    start = time.perf_counter()
    for _ in range(n):
        io.read_all()
        counts = io.encoder_counts()
        command[0] = 1e-6 * float(counts[0])
        io.set_current(command)
        io.write_all()
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--port", default="sim")
    parser.add_argument("--cycles", type=int, default=2000)
    parser.add_argument("--rounds", type=int, default=7)
    args = parser.parse_args()
    io = firelink.IoSystem(args.port)
    n = args.cycles
    rust, py, arrays = [], [], []
    io.run_cycles(1000)
    for _ in range(args.rounds):
        rust.append(io.run_cycles(n) / n * 1e6)
        py.append(python_loop(io, n) / n * 1e6)
        arrays.append(python_loop_with_arrays(io, n) / n * 1e6)
    r, p, a = statistics.median(rust), statistics.median(py), statistics.median(arrays)
    print(f"port {args.port}: {len(io.boards)} boards, {io.axes} axes, {n} cycles x {args.rounds} rounds (medians)")
    print(f"  Rust loop                         {r:8.2f} us/cycle")
    print(f"  Python read_all()+write_all()     {p:8.2f} us/cycle   overhead {p - r:6.2f} us")
    print(f"  Python, plus encoder array and set_current  {a:8.2f} us/cycle   overhead {a - r:6.2f} us")


if __name__ == "__main__":
    main()
