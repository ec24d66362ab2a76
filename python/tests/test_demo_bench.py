"""The demo and the benchmark from Python, with typed reports."""

import datetime
import itertools
from pathlib import Path

import pytest

import firelink

ONE_BOARD = Path(__file__).resolve().parents[2] / "configs" / "bench-1board.json"


def test_the_demo_runs_and_reports():
    r = firelink.run_demo(duration=0.1)
    assert r.verdict == "ok"
    assert (r.boards, r.axes) == (8, 28)
    assert r.errors.total == 0
    assert r["protocol"] == "broadcast"
    assert set(r.tracking_error) == {"MTML", "MTMR", "PSM1", "PSM2"}
    d = r.to_dict()
    assert isinstance(d, dict) and d["axes"] == 28
    assert '"axes": 28' in r.to_json()
    with pytest.raises(AttributeError):
        r.axes = 3


def test_both_levels_of_detail_give_the_same_demo():
    wall = {"wall_time_s", "speed_vs_real_time", "cycle_time_us", "compute_time_us", "detail"}
    runs = {d: firelink.run_demo(duration=0.1, detail=d).to_dict() for d in ("fast", "packet")}
    fast, packet = ({k: v for k, v in r.items() if k not in wall} for r in runs.values())
    assert fast == packet
    assert runs["fast"]["detail"]["detail"] == "fast"
    assert runs["fast"]["detail"]["packet_level_cycles"] == 0
    assert runs["packet"]["detail"]["fast_cycles"] == 0
    assert runs["packet"]["detail"]["packet_level_cycles_why"]["chosen"] > 0


def test_an_injected_fault_is_detected_and_amplifiers_end_off():
    r = firelink.run_demo(duration=0.1, fault="board-loss")
    assert r.verdict == "ok"
    assert r.fault.board == 4
    assert r.amplifiers_on_after_fault is False


def test_the_demo_takes_a_configuration(configs_dir):
    r = firelink.run_demo(duration=0.1, config=configs_dir / "bench-1board.json")
    assert (r.boards, r.axes) == (1, 4)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"fault": "meteor"},
        {"protocol": "carrier-pigeon"},
        {"rate": 0},
        {"port": "nowhere"},
        {"watchdog_ms": -5},
        {"pacing": "sometimes"},
        {"firmware": "10"},
        {"detail": "exact"},
        {"timeout": 0},
        {"timeout": 61},
    ],
)
def test_bad_demo_options_raise(kwargs):
    with pytest.raises(firelink.FirelinkError):
        firelink.run_demo(duration=0.05, **kwargs)


def test_a_sub_tick_watchdog_is_refused_not_run_with_the_watchdog_off():
    # 1e-7 ms used to become 0 ticks: the watchdog off without a word, and
    # a stopped host never detected.
    with pytest.raises(firelink.InvalidRequest, match="one firmware tick"):
        firelink.run_demo(duration=0.05, watchdog_ms=1e-7, fault="stop-host")


def test_the_demo_with_the_watchdog_off_warns():
    with pytest.warns(UserWarning, match="watchdogs are OFF"):
        r = firelink.run_demo(duration=0.05, watchdog_ms="off", config=ONE_BOARD)
    assert r.watchdog.period_ms == 0


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"duration": 1e300}, "duration 1e300 s is out of range: it must be above 0 s and at most 86400 s"),
        ({"duration": 86400.5}, "duration 86400.5 s is out of range"),
        ({"duration": 0}, "duration 0 s is out of range"),
        ({"duration": float("inf")}, "duration inf s"),
        ({"duration": "3"}, "duration must be a number above 0 s and at most 86400 s, not str"),
        ({"rate": 1e6}, "rate 1000000 Hz is out of range: it must be from 1 to 100000 Hz"),
        ({"rate": 0.5}, "rate 0.5 Hz is out of range"),
        ({"rate": None}, "rate must be a number"),
        ({"watchdog_ms": 1e300}, "watchdog period 1e300 ms is out of range"),
        ({"config": 3}, "config .* must be a str or os.PathLike, not int"),
        ({"pacing": 1}, "pacing must be a string"),
    ],
)
def test_demo_numbers_are_bounded_and_named(kwargs, match):
    with pytest.raises(firelink.InvalidRequest, match=match):
        firelink.run_demo(**{"duration": 0.05, **kwargs})


def test_the_bench_and_its_figure(tmp_path):
    png = tmp_path / "fig11.png"
    r = firelink.run_bench(transports=["sim"], boards=[2, 8, 32], cycles=20, plot=png)
    assert len(r.results) == 6
    modelled = [p for p in r.results if p.model]
    assert [p.boards for p in modelled] == [32, 32]
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"transports": ["carrier"]}, "unknown transport"),
        ({"transports": []}, "at least one transport"),
        ({"boards": [0]}, "board count 0 is out of range"),
        ({"boards": [32]}, "extrapolated"),
        ({"boards": [2.5]}, "board count must be an integer"),
        ({"boards": [2] * 65}, "more than 64"),
        ({"boards": itertools.count(1)}, "more than 64"),  # endless: refused, not followed
        ({"cycles": 0}, "cycles 0 is out of range: it must be 1 to 1000000"),
        ({"cycles": 10**7}, "cycles 10000000 is out of range"),
        ({"cycles": 5.0}, "cycles must be an integer"),
        ({"protocols": ["x"]}, "unknown protocol"),
        ({"protocols": 5}, "protocols must be a list"),
        ({"plot": 5}, "plot must be a str or os.PathLike"),
    ],
)
def test_bad_bench_options_raise(kwargs, match):
    with pytest.raises(firelink.InvalidRequest, match=match):
        firelink.run_bench(**{"transports": ["sim"], "boards": [2], "cycles": 5, **kwargs})


# What a run measures on the machine's clock; everything else is a pure
# function of the arguments (virtual time).
WALL_CLOCK = {"cycle_time_us", "compute_time_us", "wall_time_s", "speed_vs_real_time"}


def _virtual(report):
    return {k: v for k, v in report.to_dict().items() if k not in WALL_CLOCK}


def test_period_and_the_older_rate_give_the_same_run():
    by_rate = _virtual(firelink.run_demo(duration=0.05, rate=1000, config=ONE_BOARD))
    assert by_rate["rate_hz"] == 1000.0
    for period in ("1ms", "1000us", "1kHz", 0.001, datetime.timedelta(milliseconds=1)):
        assert _virtual(firelink.run_demo(duration=0.05, period=period, config=ONE_BOARD)) == by_rate, period
    # Neither given: 6 kHz, as before.
    assert firelink.run_demo(duration=0.02, config=ONE_BOARD).rate_hz == 6000.0
    assert firelink.run_demo(duration=0.02, period="6kHz", config=ONE_BOARD).rate_hz == 6000.0


@pytest.mark.parametrize("rate", [1000, 6000.0, None, "1ms"])
def test_period_and_rate_together_are_refused_naming_both(rate):
    with pytest.raises(firelink.InvalidRequest, match=r"give period= or rate=, not both"):
        firelink.run_demo(duration=0.05, period="1ms", rate=rate)


@pytest.mark.parametrize(
    "period, match",
    [
        ("5us", "servo period 5 us: out of range, 10 us to 1 s"),
        ("2 s", "servo period 2 s: out of range"),
        ("200kHz", "out of range, 10 us to 1 s \\(100 kHz to 1 Hz\\)"),
        (0, "servo period 0 s: out of range"),
        (-0.001, "out of range"),
        (1.5, "servo period 1.5 s: out of range"),
        (float("nan"), "out of range"),
        (float("inf"), "out of range"),
        (10**400, "out of range"),
        ("1000", "no unit"),
        ("1 fortnight", "unknown unit"),
        ("", "no unit"),
        (True, "period must be a string with its unit .* or a number of seconds, not bool"),
        ([1], "not list"),
    ],
)
def test_a_bad_period_is_refused_with_the_reason(period, match):
    with pytest.raises(firelink.InvalidRequest, match=match):
        firelink.run_demo(duration=0.05, period=period)
