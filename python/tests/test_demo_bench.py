"""The demo and the benchmark from Python, with typed reports."""

import pytest

import firelink


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
        {"firmware": "9"},
    ],
)
def test_bad_demo_options_raise(kwargs):
    with pytest.raises(firelink.FirelinkError):
        firelink.run_demo(duration=0.05, **kwargs)


def test_the_bench_and_its_figure(tmp_path):
    png = tmp_path / "fig11.png"
    r = firelink.run_bench(transports=["sim"], boards=[2, 8, 32], cycles=20, plot=png)
    assert len(r.results) == 6
    modelled = [p for p in r.results if p.model]
    assert [p.boards for p in modelled] == [32, 32]
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    "kwargs",
    [{"transports": ["carrier"]}, {"boards": [0]}, {"boards": [32]}, {"cycles": 0}, {"protocols": ["x"]}],
)
def test_bad_bench_options_raise(kwargs):
    with pytest.raises(firelink.FirelinkError):
        firelink.run_bench(**{"transports": ["sim"], "boards": [2], "cycles": 5, **kwargs})
