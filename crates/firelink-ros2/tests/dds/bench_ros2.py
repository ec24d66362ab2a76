"""Figures for BENCHMARKS.md: servo_jp latency from the DDS source stamp to
applied (the write block of the cycle that carried it sent), split into
DDS delivery plus the node's wake-up and the wait for the write block; the
measured_js and control rates achieved against the asked ones; the cycles
that carried each point and how the robot loop's cycles started (early for
a command, on schedule, overrun); and the robot thread's CPU time per
cycle with ROS 2 attached and without. Runs inside a network namespace it
creates (root).

    FIRELINK_ROS2_BIN=target/release/firelink-ros2 python crates/firelink-ros2/tests/dds/bench_ros2.py \\
        [--before OLD_BINARY] [--no-rt-too] [--client-fifo 60] [--publish-hz 500] [--cost-pairs 6] \\
        [--cost-seconds 3]

`--no-rt-too`: the binary under test also runs with `--no-rt` (every
thread at normal priority), to show what the real-time settings do.

Latency: each binary serves two clients in turn, one streaming servo_jp at
its own 200 Hz (arrivals at any phase of the control cycle) and one
answering each measured_js sample at once (`--react`, a loop closed over
ROS 2).

Cost: the binary under test runs `--cost-pairs` pairs of short runs, with
ROS 2 (the 200 Hz stream client) and without (`--no-dds --servo-stream
PSM1`: the robot brought up the same way, following the same stream made
in the node's process, so the robot loop does the same work: an arm that
follows a stream costs more per cycle than one holding still), the order
alternating from pair to pair; per run the median of the robot thread's CPU time per cycle over
the cycles it was Active, and the median over pairs of the ratio with /
without. Interleaving pairs and taking the median of their ratios keeps
what else the machine does at the time out of the figure better than one
long run of each.

Prints the JSON of every run, then one table of everything.
"""

import argparse
import json
import os
import random
import statistics
import subprocess
import sys

sys.path.insert(0, os.path.dirname(__file__))
import test_ros2 as t  # noqa: E402


# `--client-fifo N`: the client runs under `chrt -f N` (set in main).
CLIENT_PREFIX: list = []


def client(ns: t.Netns, arm: str, react: bool, seconds: float) -> dict:
    env = {**os.environ, "ROS_DOMAIN_ID": "7", "CYCLONEDDS_URI":
           "<CycloneDDS><Domain><Id>7</Id></Domain></CycloneDDS>"}
    mode = ["--react"] if react else []
    out = subprocess.run(["ip", "netns", "exec", ns.name, *CLIENT_PREFIX, sys.executable, t.CLIENT, "--arm", arm,
                          "--seconds", str(seconds), *mode], capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stdout + out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def with_dds(ns: t.Netns, binary: str, publish_hz: int, react: bool, seconds: float = 5.0,
             extra: list = ()) -> dict:
    node = t.robot(ns, binary, publish_hz, *extra)
    try:
        result = client(ns, "PSM1", react, seconds)
    finally:
        report = t.stop(node)
    return {"client": result, "node": report}


def without_dds(ns: t.Netns, binary: str, seconds: float) -> dict:
    alone = subprocess.run(
        ["ip", "netns", "exec", ns.name, binary, "--port", "sim", "--rate", "1000", "--no-dds", "--servo-stream", "PSM1",
         "--seconds", str(max(1, round(seconds)))], capture_output=True, text=True, check=True)
    return json.loads(alone.stdout.strip().splitlines()[-1])


def summary(run: dict) -> dict:
    node, result = run["node"], run["client"]
    return {
        "servo_jp_sent_received_applied": [result["servo_sent"], node["servo_jp_received"], node["servo_jp_applied"]],
        "latency_us_p50_p99_max": node["servo_latency_us"],
        "transit_us_p50_p99_max": node.get("servo_transit_us"),
        "delivery_us_p50_p99_max": node.get("servo_delivery_us"),
        "take_us_p50_p99_max": node.get("servo_take_us"),
        "wait_us_p50_p99_max": node.get("servo_wait_us"),
        "to_cycle_us_p50_p99_max": node.get("servo_to_cycle_us"),
        "cycle_us_p50_p99_max": node.get("servo_cycle_us"),
        "publish_frame_us_median_p99": node.get("publish_frame_us"),
        "realtime": node.get("realtime"),
        "applied_by_cycle_k1_k2_later": node.get("servo_applied_by_cycle"),
        "measured_js_hz": node["measured_js_hz"],
        "measured_js_asked_hz": node.get("measured_js_asked_hz"),
        "control_hz": node.get("control_hz"),
        "control_asked_hz": node.get("control_asked_hz"),
        "cycle_starts_early_scheduled_overrun": node.get("cycle_starts"),
        "tracking_rms_rad": result["tracking_rms_rad"],
        "busy_cpu_us_median_p99": node.get("control_busy_cpu_us"),
        "busy_us_median_p99": node.get("control_busy_us"),
        "cycle_us_median_p99": node["control_cycle_us"],
    }


def cost_pairs(ns: t.Netns, binary: str, publish_hz: int, pairs: int, seconds: float) -> dict:
    rows = []
    for k in range(pairs):
        order = ("with", "without") if k % 2 == 0 else ("without", "with")
        row = {}
        for which in order:
            if which == "with":
                row["with"] = with_dds(ns, binary, publish_hz, False, seconds)["node"]["control_busy_cpu_us"][0]
            else:
                row["without"] = without_dds(ns, binary, seconds)["control_busy_cpu_us"][0]
        row["ratio"] = row["with"] / max(row["without"], 1e-9)
        rows.append(row)
    return {
        "pairs": rows,
        "median_cpu_with_us": statistics.median(r["with"] for r in rows),
        "median_cpu_without_us": statistics.median(r["without"] for r in rows),
        "median_ratio": statistics.median(r["ratio"] for r in rows),
        "median_ratio_ci95": bootstrap_ci([r["ratio"] for r in rows]),
    }


def bootstrap_ci(ratios: list, resamples: int = 10000, seed: int = 1) -> list:
    """A 95 % confidence interval of the median of `ratios` (percentile
    bootstrap, seeded: the same pairs give the same interval)."""
    if not ratios:
        return [None, None]
    rng = random.Random(seed)
    medians = sorted(statistics.median(rng.choices(ratios, k=len(ratios))) for _ in range(resamples))
    return [medians[int(0.025 * resamples)], medians[int(0.975 * resamples) - 1]]


def ms(us: list) -> str:
    return " / ".join(f"{u / 1000:.2f}" for u in us)


def table(out: dict) -> str:
    runs = out["runs"]
    cols = list(runs)
    lines = ["| figure | " + " | ".join(cols) + " |", "|---|" + "---:|" * len(cols)]

    def row(name, f):
        lines.append(f"| {name} | " + " | ".join(f(runs[c]) for c in cols) + " |")

    row("servo_jp sent / received / applied", lambda r: " / ".join(map(str, r["servo_jp_sent_received_applied"])))
    row("latency p50 / p99 / max, ms", lambda r: ms(r["latency_us_p50_p99_max"]))
    row("transit p50 / p99 / max, ms", lambda r: ms(r["transit_us_p50_p99_max"] or [0, 0, 0]))
    row("- of which DDS delivery (source to RustDDS received)",
        lambda r: ms(r["delivery_us_p50_p99_max"] or [0, 0, 0]))
    row("- of which the node's take (received to queued)", lambda r: ms(r["take_us_p50_p99_max"] or [0, 0, 0]))
    row("wait p50 / p99 / max, ms", lambda r: ms(r["wait_us_p50_p99_max"] or [0, 0, 0]))
    row("- of which to the carrying cycle's start", lambda r: ms(r["to_cycle_us_p50_p99_max"] or [0, 0, 0]))
    row("- of which that cycle up to applied", lambda r: ms(r["cycle_us_p50_p99_max"] or [0, 0, 0]))
    row("carried by k+1 / k+2 / later", lambda r: " / ".join(map(str, r["applied_by_cycle_k1_k2_later"] or [])))
    row("measured_js, Hz (% of asked)",
        lambda r: f"{r['measured_js_hz']:.1f} ({100 * r['measured_js_hz'] / (r['measured_js_asked_hz'] or 1):.1f} %)")
    row("control, Hz (% of asked)",
        lambda r: "" if r["control_hz"] is None else
        f"{r['control_hz']:.1f} ({100 * r['control_hz'] / (r['control_asked_hz'] or 1):.1f} %)")
    row("cycles early / on schedule / overrun",
        lambda r: " / ".join(map(str, r["cycle_starts_early_scheduled_overrun"] or [])))
    row("robot thread CPU per cycle, median us", lambda r: f"{(r['busy_cpu_us_median_p99'] or [0])[0]:.1f}")
    row("node: one frame published, median / p99 us",
        lambda r: " / ".join(f"{u:.0f}" for u in (r["publish_frame_us_median_p99"] or [])))
    row("real-time settings applied", lambda r: "" if r["realtime"] is None else
        ("yes" if r["realtime"]["applied"] else ("no" if r["realtime"]["requested"] else "off (--no-rt)")))
    cost = out.get("cost")
    text = "\n".join(lines)
    if cost:
        pairs = ", ".join(f"{p['with']:.1f}/{p['without']:.1f}={p['ratio']:.3f}" for p in cost["pairs"])
        text += (f"\n\nrobot thread CPU per cycle, with / without ROS 2 (us), {len(cost['pairs'])} interleaved pairs: "
                 f"{pairs}\nmedian with {cost['median_cpu_with_us']:.1f} us, without {cost['median_cpu_without_us']:.1f} us, "
                 f"median of ratios {cost['median_ratio']:.3f} (95 % interval "
                 f"{cost['median_ratio_ci95'][0]:.3f}-{cost['median_ratio_ci95'][1]:.3f}, bootstrap)")
    text += f"\n\nload average at start {' '.join(out['loadavg_at_start'])}, at end {' '.join(out['loadavg_at_end'])}"
    return text


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--before", help="an earlier firelink-ros2 binary, run the same way first")
    parser.add_argument("--no-rt-too", action="store_true",
                        help="also run the binary under test with --no-rt (every thread at normal priority)")
    parser.add_argument("--client-fifo", type=int, metavar="PRIORITY",
                        help="run the Python client under chrt -f PRIORITY (a real-time client: its own "
                             "send jitter, which counts in transit, then does not wait behind other work)")
    parser.add_argument("--publish-hz", type=int, default=500)
    parser.add_argument("--cost-pairs", type=int, default=6, help="interleaved with/without runs (0: none)")
    parser.add_argument("--cost-seconds", type=float, default=3.0)
    args = parser.parse_args()
    with open("/proc/loadavg") as f:
        load = f.read().split()[:3]
    out = {"publish_hz": args.publish_hz, "client_fifo": args.client_fifo, "loadavg_at_start": load, "runs": {}}
    if args.client_fifo:
        CLIENT_PREFIX[:] = ["chrt", "-f", str(args.client_fifo)]
    ns = t.Netns()
    try:
        ns.run("ip", "link", "set", "lo", "up")
        ns.multicast_on("lo")
        binaries = ([("before", args.before, [])] if args.before else []) + \
            ([("after --no-rt", t.BIN, ["--no-rt"])] if args.no_rt_too else []) + [("after", t.BIN, [])]
        for label, binary, extra in binaries:
            for mode, react in (("stream 200 Hz", False), ("react", True)):
                print(f"{label}: {mode}", file=sys.stderr, flush=True)
                out["runs"][f"{label}: {mode}"] = summary(with_dds(ns, binary, args.publish_hz, react,
                                                                   extra=extra))
        if args.cost_pairs > 0:
            out["cost"] = cost_pairs(ns, t.BIN, args.publish_hz, args.cost_pairs, args.cost_seconds)
    finally:
        ns.delete()
    with open("/proc/loadavg") as f:
        out["loadavg_at_end"] = f.read().split()[:3]
    print(json.dumps(out, indent=1))
    print()
    print(table(out))


if __name__ == "__main__":
    main()
