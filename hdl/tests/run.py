"""Build the Verilog with Icarus and run the cocotb test modules.

    hdl/.venv/bin/python hdl/tests/run.py [module ...]

Each test module names its top level and parameters in TESTS below. The
run stops with a non-zero status when any test fails.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

from cocotb_tools.runner import get_runner

HERE = Path(__file__).resolve().parent
RTL = HERE.parent / "rtl"
BUILD = HERE.parent / "build"

# module -> (top level, parameters, extra sources)
TESTS = {
    "test_crc": ("crc32_1394", {}, []),
    "test_lreq": ("phy_lreq_tx", {}, []),
    "test_slicer": ("command_slicer", {"BOARD_ID": 2}, []),
    "test_watchdog": ("board_watchdog", {"POWER_UP_TICKS": 4}, []),
    "test_power": ("board_power", {"HOLD_CLOCKS": 1000, "MISMATCH_CLOCKS": 20000}, []),
    "test_node": ("firelink_node", {"BOARD_ID": 3}, []),
    "test_bus": ("tb_bus", {"CHAIN": 1}, [HERE / "tb_bus.v"]),
    "test_tdma": ("tb_bus", {"CHAIN": 0}, [HERE / "tb_bus.v"]),
    "test_crosscheck": ("firelink_node", {"BOARD_ID": 1}, []),
}


def main(argv: list[str]) -> int:
    names = argv or list(TESTS)
    sources = sorted(RTL.glob("*.v"))
    failed = 0
    total = 0
    for name in names:
        top, params, extra = TESTS[name]
        build = BUILD / f"{name}"
        runner = get_runner("icarus")
        t0 = time.monotonic()
        runner.build(sources=sources + extra, hdl_toplevel=top, parameters=params,
                     build_dir=build, timescale=("1ps", "1ps"), always=True,
                     build_args=["-Wall", "-Wno-timescale", "-Wno-sensitivity-entire-array"])
        results = runner.test(hdl_toplevel=top, test_module=name, build_dir=build,
                              test_dir=HERE, results_xml=str(build / "results.xml"),
                              extra_env={"PYTHONPATH": str(HERE)})
        fails = _count_failures(results)
        tests = _count_tests(results)
        total += tests
        failed += fails
        print(f"== {name}: {tests - fails} passed, {fails} failed ({time.monotonic() - t0:.1f} s)")
    print(f"hdl: {total - failed} passed, {failed} failed")
    return 1 if failed else 0


def _count_failures(results_xml) -> int:
    import xml.etree.ElementTree as ET
    root = ET.parse(results_xml).getroot()
    return sum(1 for case in root.iter("testcase") if case.find("failure") is not None
               or case.find("error") is not None)


def _count_tests(results_xml) -> int:
    import xml.etree.ElementTree as ET
    return sum(1 for _ in ET.parse(results_xml).getroot().iter("testcase"))


if __name__ == "__main__":
    os.environ.setdefault("COCOTB_REDUCED_LOG_FMT", "1")
    sys.exit(main(sys.argv[1:]))
