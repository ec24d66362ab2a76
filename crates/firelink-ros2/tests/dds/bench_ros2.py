"""Figures for BENCHMARKS.md: servo_jp latency from the DDS source stamp to
applied (the write block of the cycle that carried it sent), split into
DDS delivery plus the node's wake-up and the wait for the next cycle; the
measured_js rate achieved against the asked one; the cycles that carried
each point; and the robot thread's work per cycle with ROS 2 attached and
without, side by side in one run. Runs inside a network namespace it
creates (root).

    FIRELINK_ROS2_BIN=target/release/firelink-ros2 python crates/firelink-ros2/tests/dds/bench_ros2.py \\
        [--before OLD_BINARY] [--publish-hz 500]

Each binary serves two clients in turn: one streaming servo_jp at its own
200 Hz (arrivals at any phase of the control cycle) and one answering each
measured_js sample at once (`--react`, a loop closed over ROS 2). After
each run of the binary under test, the robot runs alone (`--no-dds`) for
as long.
"""

import argparse
import json
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(__file__))
import test_ros2 as t  # noqa: E402


def with_dds(ns: t.Netns, binary: str, publish_hz: int, react: bool) -> dict:
    node = t.robot(ns, binary, publish_hz)
    try:
        client = t.client(ns, "PSM1", react=react)
    finally:
        report = t.stop(node)
    return {"client": client, "node": report}


def without_dds(ns: t.Netns, binary: str, seconds: float) -> dict:
    alone = subprocess.run(
        ["ip", "netns", "exec", ns.name, binary, "--port", "sim", "--rate", "1000", "--no-dds", "--seconds",
         str(max(1, round(seconds)))], capture_output=True, text=True, check=True)
    return json.loads(alone.stdout.strip().splitlines()[-1])


def summary(run: dict) -> dict:
    node, client = run["node"], run["client"]
    return {
        "servo_jp_sent_received_applied": [client["servo_sent"], node["servo_jp_received"], node["servo_jp_applied"]],
        "latency_us_p50_p99_max": node["servo_latency_us"],
        "transit_us_p50_p99_max": node.get("servo_transit_us"),
        "wait_us_p50_p99_max": node.get("servo_wait_us"),
        "applied_by_cycle_k1_k2_later": node.get("servo_applied_by_cycle"),
        "measured_js_hz": node["measured_js_hz"],
        "measured_js_asked_hz": node.get("measured_js_asked_hz"),
        "tracking_rms_rad": client["tracking_rms_rad"],
        "busy_us_median_p99": node.get("control_busy_us"),
        "busy_cpu_us_median_p99": node.get("control_busy_cpu_us"),
        "cycle_us_median_p99": node["control_cycle_us"],
        "compute_us_median_p99": node["control_compute_us"],
    }


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--before", help="an earlier firelink-ros2 binary, run the same way first")
    parser.add_argument("--publish-hz", type=int, default=500)
    args = parser.parse_args()
    with open("/proc/loadavg") as f:
        load = f.read().split()[:3]
    out = {"publish_hz": args.publish_hz, "loadavg_at_start": load, "runs": {}}
    ns = t.Netns()
    try:
        ns.run("ip", "link", "set", "lo", "up")
        ns.multicast_on("lo")
        binaries = ([("before", args.before)] if args.before else []) + [("after", t.BIN)]
        for label, binary in binaries:
            for mode, react in (("stream_200hz", False), ("react", True)):
                run = with_dds(ns, binary, args.publish_hz, react)
                entry = summary(run)
                if label == "after":
                    alone = without_dds(ns, binary, run["node"]["seconds"])
                    entry["without_dds_busy_us_median_p99"] = alone["control_busy_us"]
                    entry["without_dds_busy_cpu_us_median_p99"] = alone["control_busy_cpu_us"]
                    entry["busy_cpu_ratio_with_over_without"] = (
                        run["node"]["control_busy_cpu_us"][0] / max(alone["control_busy_cpu_us"][0], 1e-9))
                    entry["without_dds_cycle_us_median_p99"] = alone["control_cycle_us"]
                    entry["busy_ratio_with_over_without"] = (
                        run["node"]["control_busy_us"][0] / max(alone["control_busy_us"][0], 1e-9))
                out["runs"][f"{label}/{mode}"] = entry
    finally:
        ns.delete()
    with open("/proc/loadavg") as f:
        out["loadavg_at_end"] = f.read().split()[:3]
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
