"""The in-process emulator as a context manager."""

import threading

import pytest

import firelink


def test_the_context_manager_always_stops_the_server(udp_timeout):
    threads_before = threading.active_count()
    with firelink.Emulator(boards=2) as emu:
        assert emu.running
        assert emu.address.startswith("udp:127.0.0.1:")
        assert len(firelink.IoSystem(emu.port(timeout=udp_timeout)).boards) == 2
    assert not emu.running
    with pytest.raises(firelink.EmulatorClosed):
        emu.port()
    assert emu.stop() is None  # stopping twice is harmless
    assert threading.active_count() == threads_before


def test_an_exception_inside_the_block_still_stops_it():
    with pytest.raises(RuntimeError, match="inside"):
        with firelink.Emulator(boards=1) as emu:
            raise RuntimeError("inside")
    assert not emu.running


def test_stop_reports_the_counters(udp_timeout):
    emu = firelink.Emulator(boards=1, firmware="7")
    port = emu.port(timeout=udp_timeout)
    assert [b.firmware for b in port.scan()] == [7]
    stats = emu.stop()
    assert stats is not None
    assert stats["datagrams"] > 0 and stats["replies"] > 0
    assert stats["malformed"] == 0


@pytest.mark.parametrize("kwargs", [{"boards": 0}, {"boards": 17}, {"firmware": "10"}])
def test_bad_emulator_options(kwargs):
    with pytest.raises(firelink.FirelinkError):
        firelink.Emulator(**kwargs)


@pytest.mark.parametrize("timeout", [0.0, -1.0, float("nan"), 1e9])
def test_a_bad_port_timeout_is_refused(timeout, udp_timeout):
    with firelink.Emulator(boards=1) as emu:
        with pytest.raises(firelink.InvalidRequest, match="timeout"):
            emu.port(timeout=timeout)
        assert len(emu.port(timeout=udp_timeout).scan()) == 1
