"""Reproduce seed 000's Fig. 11: I/O time per cycle against boards.

Runs the benchmark (simulated bus with the seed-000 PC model; add
``--udp`` to also measure over loopback UDP against an in-process
emulator), prints the table next to the paper's figures and draws the
figure with matplotlib from the typed report (``fig11.png``).

    python examples/fig11.py [--udp] [--cycles 200] [--out fig11.png]
"""

from __future__ import annotations

import argparse

import firelink


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--udp", action="store_true", help="also measure over loopback UDP")
    parser.add_argument("--cycles", type=int, default=200)
    parser.add_argument("--out", default="fig11.png")
    args = parser.parse_args()
    transports = ["sim", "udp"] if args.udp else ["sim"]
    report = firelink.run_bench(transports=transports, boards=[1, 2, 4, 8, 16, 32, 62], cycles=args.cycles)

    print(f"{'transport':<9} {'protocol':<10} {'boards':>6} {'I/O median, us':>15}  source")
    for p in report.results:
        print(f"{p.transport:<9} {p.protocol_asked:<10} {p.boards:>6} {p.io_time_us.median:>15.1f}  "
              f"{'model' if p.model else 'measured'}")
    paper = report.paper
    sim8 = {p.protocol_asked: p.io_time_us.median for p in report.results if p.transport == "sim" and p.boards == 8}
    for name, ours, theirs in [("sequential", sim8["sequential"], paper.sequential_8_us),
                               ("broadcast", sim8["broadcast"], paper.broadcast_8_us)]:
        print(f"8 boards, {name}: simulated {ours:.1f} us, paper {theirs:.1f} us ({100 * (ours / theirs - 1):+.1f} %)")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 5.5))
    for transport in transports:
        for protocol, colour in [("sequential", "tab:red"), ("broadcast", "tab:blue")]:
            pts = [p for p in report.results if p.transport == transport and p.protocol_asked == protocol]
            style = "-" if transport == "sim" else ":"
            ax.plot([p.boards for p in pts], [p.io_time_us.median for p in pts], style, color=colour,
                    label=f"{transport} {protocol}")
            measured = [p for p in pts if not p.model]
            modelled = [p for p in pts if p.model]
            ax.plot([p.boards for p in measured], [p.io_time_us.median for p in measured], "o", color=colour)
            ax.plot([p.boards for p in modelled], [p.io_time_us.median for p in modelled], "o",
                    markerfacecolor="none", color=colour)
    ax.plot([8, 8], [paper.sequential_8_us, paper.broadcast_8_us], "kx", markersize=10, label="paper, 8 boards")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xticks([1, 2, 4, 8, 16, 32, 62], labels=["1", "2", "4", "8", "16", "32", "62"])
    ax.set_xlabel("boards on the bus (log scale; hollow: model beyond 16 boards)")
    ax.set_ylabel("I/O time per cycle, us (log scale)")
    ax.set_title("Seed 000, Fig. 11: I/O time per servo cycle")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(args.out, dpi=100)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
