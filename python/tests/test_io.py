"""The I/O system: cycles, per-axis arrays, commands, safety controls."""

import numpy as np
import pytest

import firelink


def settle(io: firelink.IoSystem, ms: int) -> None:
    """Cycle once per millisecond of virtual time."""
    for _ in range(ms):
        io.cycle()
        io.wait(1e-3)


def powered(io: firelink.IoSystem) -> None:
    io.set_watchdog(20)
    io.set_relay(True)
    io.set_power(True)
    settle(io, 200)  # the motor supply ramps up over a few ms


def test_arrays_have_one_value_per_axis_with_documented_types():
    io = firelink.IoSystem("sim")
    assert io.read_all()
    assert io.axes == 32 and len(io.boards) == 8
    for values, dtype in [
        (io.encoder_counts(), np.int32),
        (io.velocity(), np.float64),
        (io.pot(), np.uint16),
        (io.current(), np.float64),
        (io.amp_enabled(), np.bool_),
        (io.dac(), np.uint16),
    ]:
        assert values.shape == (32,)
        assert values.dtype == dtype
    assert io.write_all()
    assert io.stats()["total_errors"] == 0


def test_power_relay_and_amplifiers_follow_the_commands():
    io = firelink.IoSystem("sim:2")
    powered(io)
    assert all(power and relay for _, power, relay, _ in io.board_status())
    io.set_amplifiers(True)
    settle(io, 20)  # the amplifiers come on a few ms after the request
    assert io.amp_enabled().all()
    io.set_amplifiers(False, board=1)
    settle(io, 20)
    amps = io.amp_enabled()
    assert amps[:4].all() and not amps[4:].any()
    with pytest.raises(firelink.InvalidRequest, match="no board 9"):
        io.set_power(False, board=9)


def test_a_current_command_moves_the_motor_and_reads_back():
    io = firelink.IoSystem("sim:1")
    powered(io)
    io.set_amplifiers(True)
    amps = np.array([0.3, 0.0, 0.0, 0.0])
    io.set_current(amps)
    assert abs(int(io.dac()[0]) - round((0.3 + 6.25) * 65536 / 12.5)) <= 1
    start = io.encoder_counts()[0]
    settle(io, 50)  # accelerating: the amplifier holds the commanded current
    assert io.current()[0] == pytest.approx(0.3, abs=0.05)
    assert io.encoder_counts()[0] != start
    io.set_dac(np.full(4, 0x8000))
    assert list(io.dac()) == [0x8000] * 4


def test_bad_commands_are_refused_and_change_nothing():
    io = firelink.IoSystem("sim:1")
    before = io.dac().copy()
    with pytest.raises(firelink.InvalidRequest, match="3 values for 4 axes"):
        io.set_dac(np.zeros(3, dtype=np.int64))
    with pytest.raises(firelink.InvalidRequest, match="DAC value"):
        io.set_dac(np.array([0, 1, 2, 70000]))
    with pytest.raises(firelink.InvalidRequest, match="6.25"):
        io.set_current(np.array([0.0, 0.0, 9.0, 0.0]))
    with pytest.raises(firelink.InvalidRequest, match="6.25"):
        io.set_current(np.array([0.0, np.nan, 0.0, 0.0]))
    with pytest.raises(firelink.InvalidRequest, match="integers, not float64"):
        io.set_dac(np.zeros(4))
    with pytest.raises(firelink.InvalidRequest, match="on must be True or False"):
        io.set_power("off")
    assert (io.dac() == before).all()
    io.set_dac([1, 2, 3, 4])  # a list is an array too
    assert list(io.dac()) == [1, 2, 3, 4]


WATCHDOG_RANGE = r"from 0\.00521 ms \(one firmware tick of 5\.208 us\) to 341\.32 ms"


@pytest.mark.parametrize("ms", [1e-9, 0, -1, 400, float("nan"), True, "x", None, [20], 2**70])
def test_a_watchdog_off_the_register_or_not_a_period_is_refused_naming_the_range(ms):
    io = firelink.IoSystem("sim:1")
    with pytest.raises(firelink.InvalidRequest, match=WATCHDOG_RANGE):
        io.set_watchdog(ms)


def test_only_the_word_off_turns_the_watchdog_off_and_it_warns():
    io = firelink.IoSystem("sim:1")
    io.set_watchdog(20)
    assert io.read_register(0, 3) & 0xFFFF == 3840  # 20 ms in 5.208 us ticks
    with pytest.warns(UserWarning, match="watchdogs are OFF"):
        io.set_watchdog("off")
    assert io.read_register(0, 3) & 0xFFFF == 0
    io.set_watchdog(0.00521)  # one tick (5.208 us): the shortest period, not off
    assert io.read_register(0, 3) & 0xFFFF == 1
    io.set_watchdog("20")  # a period as text, as on the command line
    assert io.read_register(0, 3) & 0xFFFF == 3840


def test_registers_through_the_io_system():
    io = firelink.IoSystem("sim:2", protocol="sequential")
    assert io.protocol == "sequential"
    assert io.read_register(1, 7) == 8
    io.write_register(1, 3, 500)
    assert io.read_register(1, 3) & 0xFFFF == 500
    with pytest.raises(firelink.InvalidRequest):
        io.read_register(12, 7)
    with pytest.raises(firelink.InvalidRequest, match="unknown protocol"):
        firelink.IoSystem("sim:1", protocol="smoke-signals")


def test_a_thousand_cycles_against_the_in_process_emulator_without_error(udp_timeout):
    with firelink.Emulator(boards=4) as emu:
        io = firelink.IoSystem(emu.port(timeout=udp_timeout))
        assert io.protocol == "broadcast"
        ok = sum(io.read_all() & io.write_all() for _ in range(1000))
        stats = io.stats()
    assert ok == 1000, stats
    assert stats["total_errors"] == 0
    assert stats["cycles"] >= 1000


def test_the_rust_loop_runs_the_same_cycles():
    io = firelink.IoSystem("sim")
    seconds = io.run_cycles(100)
    assert seconds > 0
    assert io.stats()["cycles"] >= 100
