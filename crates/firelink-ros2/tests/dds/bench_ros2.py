"""Figures for BENCHMARKS.md: servo_jp command-to-applied latency, the
measured_js rate achieved, and the control loop's compute time with and
without ROS 2 attached. Runs inside a network namespace it creates (root).

    FIRELINK_ROS2_BIN=target/release/firelink-ros2 python crates/firelink-ros2/tests/dds/bench_ros2.py
"""

import json
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(__file__))
import test_ros2 as t  # noqa: E402


def main() -> None:
    ns = t.Netns()
    try:
        ns.run("ip", "link", "set", "lo", "up")
        ns.multicast_on("lo")
        node = t.robot(ns)
        try:
            client = t.client(ns, "PSM1")
        finally:
            with_dds = t.stop(node)
        alone = subprocess.run(
            ["ip", "netns", "exec", ns.name, t.BIN, "--port", "sim", "--rate", "1000", "--no-dds", "--seconds",
             str(round(with_dds["seconds"]))], capture_output=True, text=True, check=True)
        without = json.loads(alone.stdout.strip().splitlines()[-1])
    finally:
        ns.delete()
    ratio = with_dds["control_compute_us"][0] / max(without["control_compute_us"][0], 1e-9)
    print(json.dumps({
        "servo_jp": {"received": with_dds["servo_jp_received"], "applied": with_dds["servo_jp_applied"],
                     "latency_us_p50_p99_max": with_dds["servo_latency_us"]},
        "measured_js_hz": with_dds["measured_js_hz"],
        "tracking_rms_rad": client["tracking_rms_rad"],
        "compute_us_median_p99_with_ros2": with_dds["control_compute_us"],
        "compute_us_median_p99_without": without["control_compute_us"],
        "compute_ratio_with_over_without": ratio,
        "cycle_us_median_p99_with_ros2": with_dds["control_cycle_us"],
        "cycle_us_median_p99_without": without["control_cycle_us"],
        "cycle_ratio_with_over_without": with_dds["control_cycle_us"][0] / max(without["control_cycle_us"][0], 1e-9),
    }, indent=1))


if __name__ == "__main__":
    main()
