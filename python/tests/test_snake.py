"""Seed 001's Snake nodes: discovery, the latch/apply cycle, the Get/Set
list, EEPROM, and bad input."""

import numpy as np
import pytest

import firelink

SNAKE_CONFIG_IDS = [0, 1, 2, 3, 4, 5]  # configs/snake-seed001.json


@pytest.fixture(scope="module")
def snake() -> firelink.SnakeSystem:
    return firelink.SnakeSystem("sim")


def test_discovery_finds_the_configurations_nodes(snake):
    assert [n.board_id for n in snake.nodes] == SNAKE_CONFIG_IDS
    assert all(n.channels == 7 for n in snake.nodes)
    assert len({n.node for n in snake.nodes}) == 6
    assert snake.axes == 42
    assert "SnakeSystem" in repr(snake)


def test_a_config_chooses_the_emulated_nodes(configs_dir):
    config = firelink.load_config(configs_dir / "snake-seed001.json")
    assert [n.board_id for n in firelink.SnakeSystem("sim", config).nodes] == SNAKE_CONFIG_IDS
    with pytest.raises(firelink.FirelinkError, match="SNAKE"):
        firelink.SnakeSystem("sim", firelink.load_config(configs_dir / "dvrk-seed000.json"))


def test_a_thousand_latch_apply_cycles_without_error():
    snake = firelink.SnakeSystem("sim")
    ok = 0
    for i in range(1000):
        ok += snake.latch_all_inputs()
        snake.set_dac(np.full(snake.axes, 0x8000 + (i % 16)))
        ok += snake.apply_all_outputs()
    stats = snake.stats()
    assert ok == 2000, stats
    assert stats["total_errors"] == 0
    assert stats["cycles"] == 1000 and stats["clean_cycles"] == 1000
    assert snake.last_cycle()[0]
    assert all(s["valid"] for s in snake.node_status())


def test_arrays_have_seven_values_per_node_with_documented_types(snake):
    assert snake.latch_all_inputs()
    for values, dtype in [
        (snake.encoder_counts(), np.int32),
        (snake.encoder_position(), np.uint32),
        (snake.encoder_overflow(), np.bool_),
        (snake.encoder_period(), np.int16),
        (snake.velocity(), np.float64),
        (snake.analog_position(), np.uint16),
        (snake.motor_current(), np.uint16),
        (snake.amp_enabled(), np.bool_),
        (snake.amp_fault(), np.bool_),
    ]:
        assert values.shape == (42,)
        assert values.dtype == dtype
    # ADC values carry the seed's +8192: 14 bits, mid-scale near rest.
    assert (snake.analog_position() <= 16383).all()
    assert (snake.motor_current() <= 16383).all()


def test_motor_voltage_goes_out_with_apply_and_reads_back():
    snake = firelink.SnakeSystem("sim")
    snake.set_motor_voltage(2, 3, 0x9000)
    assert snake.pending_motor_voltage(2, 3) == 0x9000
    assert snake.pending_motor_voltage(2, 4) is None
    assert snake.apply_all_outputs()
    assert snake.pending_motor_voltage(2, 3) is None  # valid bits clear after apply
    assert snake.dac(2, 3)[0] == 0x9000
    assert snake.dac(2, 4)[0] == 0x8000  # untouched: the channel was not valid
    codes = np.arange(42) + 0x8000
    snake.set_dac(codes)
    snake.apply_all_outputs()
    assert snake.dac(5, 7)[0] == 0x8000 + 41
    snake.set_motor_current(2, 3, 12345)
    assert snake.dac(2, 3) == (0x8000 + 2 * 7 + 2, 12345)


def test_amplifiers_follow_the_buffered_and_immediate_controls():
    snake = firelink.SnakeSystem("sim")
    snake.set_amplifiers(True, board=1)
    snake.apply_all_outputs()
    snake.latch_all_inputs()
    amps = snake.amp_enabled()
    assert amps[7:14].all() and not amps[:7].any() and not amps[14:].any()
    snake.set_amplifier(1, 2, False)
    snake.cycle()
    snake.latch_all_inputs()
    assert list(snake.amp_enabled()[7:14]) == [True, False] + [True] * 5
    snake.set_power_control(1, 0b111_1111, 0)
    snake.latch_all_inputs()
    assert not snake.amp_enabled().any()
    assert snake.node_status()[1]["amp_enable"] == 0


def test_encoder_preload_and_reset():
    snake = firelink.SnakeSystem("sim")
    snake.set_encoder_preload(0, 5, 0x800100)
    snake.latch_all_inputs()
    assert snake.encoder_position()[4] == 0x800100
    assert snake.encoder_counts()[4] == 0x100
    snake.reset_encoder(0, 5)
    snake.latch_all_inputs()
    assert snake.encoder_position()[4] == 0x800000
    assert snake.encoder_counts()[4] == 0


def test_pot_wiper_gain_and_analog_switches_round_trip(snake):
    assert snake.digital_pot_wiper(3, 2) == 375  # the seed's nominal
    snake.set_digital_pot_wiper(3, 2, 649)
    assert snake.digital_pot_wiper(3, 2) == 649
    assert snake.feedback_gain(3, 2) == pytest.approx(firelink.SnakeSystem.wiper_gain(649))
    assert firelink.SnakeSystem.wiper_gain(375) == pytest.approx(2.01, abs=0.01)
    assert snake.digital_pot_wiper(3, 1) == 375  # another channel is untouched
    assert snake.analog_switches(3, 2) == (False, False)  # torque mode
    snake.set_analog_switches(3, 2, True, o2=True)
    assert snake.analog_switches(3, 2) == (True, True)
    snake.set_analog_switches(3, 2, False)
    assert snake.analog_switches(3, 2) == (False, False)


def test_watchdog_round_trip(snake):
    snake.set_watchdog(20)
    assert all(snake.watchdog(b) == pytest.approx(20, abs=0.01) for b in SNAKE_CONFIG_IDS)
    with pytest.warns(UserWarning, match="watchdogs are OFF"):
        snake.set_watchdog("off")
    assert snake.watchdog(0) == 0
    for refused in (0, 1e-9, 0.005, -1, 400, float("nan"), True, "x"):
        with pytest.raises(firelink.InvalidRequest, match="one firmware tick"):
            snake.set_watchdog(refused)
    assert snake.watchdog(0) == 0  # the refusals changed nothing


def test_eeprom_raw_and_float_round_trip_and_write_protection():
    snake = firelink.SnakeSystem("sim")
    index = firelink.SnakeSystem.eeprom_index(4, 3)
    assert index == 0x43
    assert snake.write_protect(1, 4)  # nodes start write-protected
    with pytest.raises(firelink.InvalidRequest, match="write protection"):
        snake.set_eeprom_raw(1, index, 0xBEEF)
    assert snake.eeprom_raw(1, index) == 0  # the refused write changed nothing
    snake.set_write_protect(1, 4, False)
    assert not snake.write_protect(1, 4)
    snake.set_eeprom_raw(1, index, 0xBEEF)
    assert snake.eeprom_raw(1, index) == 0xBEEF
    for value in (3.57727, -1.5, 0.0, 1e30):
        snake.set_eeprom_float(1, 0x4C, value)
        assert snake.eeprom_float(1, 0x4C) == pytest.approx(value, rel=1e-7)
    assert snake.eeprom_raw(1, 0x4C) == 0x7149 and snake.eeprom_raw(1, 0x4D) == 0xF2CA  # 1e30
    snake.set_write_protect(1, 4, True)
    with pytest.raises(firelink.InvalidRequest, match="write protection"):
        snake.set_eeprom_float(1, 0x4C, 2.0)
    assert snake.eeprom_float(1, 0x4C) == pytest.approx(1e30, rel=1e-7)
    assert snake.eeprom_raw(2, index) == 0  # another node's EEPROM is its own


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda s: s.digital_pot_wiper(0, 8), "channel 8"),
        (lambda s: s.digital_pot_wiper(0, 0), "channel 0"),
        (lambda s: s.set_motor_voltage(0, -1, 0x8000), "channel -1"),
        (lambda s: s.set_digital_pot_wiper(0, 1, 1024), "wiper 1024"),
        (lambda s: s.set_digital_pot_wiper(0, 1, -5), "wiper -5"),
        (lambda s: s.eeprom_raw(0, 0x1E), "EEPROM word"),  # word 14
        (lambda s: s.eeprom_raw(0, 0x0D), "channel"),  # channel 0
        (lambda s: s.eeprom_raw(0, 0x100), "EEPROM index"),
        (lambda s: s.eeprom_float(0, 0x1D), "first of its two words"),
        (lambda s: s.set_eeprom_raw(0, 0x10, 70000), "EEPROM value"),
        (lambda s: s.set_eeprom_float(0, 0x10, 1e300), "32-bit float"),
        (lambda s: firelink.SnakeSystem.eeprom_index(1, 14), "EEPROM word"),
        (lambda s: s.set_motor_voltage(0, 1, 1 << 70), "1180591620717411303424 is out of range"),
        (lambda s: s.set_motor_current(0, 1, 65536), "current limit"),
        (lambda s: s.set_encoder_preload(0, 1, 1 << 24), "encoder preload"),
        (lambda s: s.set_power_control(0, 0x80, 0), "mask"),
        (lambda s: s.set_watchdog(400), "watchdog"),
        (lambda s: s.set_watchdog(float("nan")), "watchdog"),
        (lambda s: s.watchdog(9), "9"),  # no such node
        (lambda s: s.set_amplifiers(True, board=12), "no Snake node 12"),
        (lambda s: s.set_motor_voltage(16, 1, 0), "board ID 16"),
        (lambda s: s.set_dac(np.zeros(41, dtype=np.int64)), "41 values for 42 axes"),
        (lambda s: s.set_dac(np.full(42, 65536)), "DAC code"),
        (lambda s: firelink.SnakeSystem.wiper_gain(2000), "wiper"),
    ],
)
def test_bad_arguments_raise_invalid_request(snake, call, match):
    with pytest.raises(firelink.InvalidRequest, match=match):
        call(snake)


def test_wrong_types_raise_invalid_request_and_change_nothing():
    snake = firelink.SnakeSystem("sim")
    with pytest.raises(firelink.InvalidRequest, match="wiper must be an integer from 0 to 1023, not str"):
        snake.set_digital_pot_wiper(0, 1, "375")  # type: ignore[arg-type]
    with pytest.raises(firelink.InvalidRequest, match="channel must be an integer from 1 to 7, not float"):
        snake.set_motor_voltage(0, 1.5, 0x8000)  # type: ignore[arg-type]
    with pytest.raises(firelink.InvalidRequest, match="board ID must be an integer from 0 to 15, not bool"):
        snake.set_motor_voltage(True, 1, 0x8000)  # type: ignore[arg-type]
    with pytest.raises(firelink.InvalidRequest, match="integers, not float64"):
        snake.set_dac(np.full(42, 0x8000, dtype=np.float64))  # type: ignore[arg-type]
    with pytest.raises(firelink.InvalidRequest, match="on must be True or False"):
        snake.set_amplifiers(1)  # type: ignore[arg-type]
    with pytest.raises(firelink.InvalidRequest, match="EEPROM float is NaN"):
        snake.set_eeprom_float(1, 0x10, float("nan"))
    assert snake.digital_pot_wiper(0, 1) == 375
    assert snake.pending_motor_voltage(0, 1) is None
    snake.set_dac([0x8000] * 42)  # a list, or any integer array, is taken
    snake.set_dac(np.full(42, 0x8000, dtype=np.uint16))
    assert snake.pending_motor_voltage(0, 1) == 0x8000


def test_bad_ports_raise_port_error():
    with pytest.raises(firelink.PortError, match="firelink.SnakeSystem: port sim:8 cannot be used"):
        firelink.SnakeSystem("sim:8")
    with pytest.raises(firelink.PortError):
        firelink.SnakeSystem("udp:not a host:x")
    with pytest.raises(firelink.PortError, match="port must be"):
        firelink.SnakeSystem(42)  # type: ignore[arg-type]
    with pytest.raises(firelink.NoBoardsError):
        firelink.SnakeSystem(firelink.open("sim:2"))  # QLA boards only: no Snake node
    with pytest.raises(firelink.InvalidRequest, match="unknown robot"):
        firelink.Emulator(robot="octopus")


def test_snake_nodes_behind_the_in_process_emulator_over_udp(udp_timeout):
    with firelink.Emulator(robot="snake") as emu:
        snake = firelink.SnakeSystem(emu.port(timeout=udp_timeout))
        assert [n.board_id for n in snake.nodes] == SNAKE_CONFIG_IDS
        ok = sum(snake.latch_all_inputs() & snake.apply_all_outputs() for _ in range(200))
        snake.set_digital_pot_wiper(4, 7, 512)
        assert snake.digital_pot_wiper(4, 7) == 512
        port_system = firelink.SnakeSystem(emu.port(timeout=udp_timeout))
        assert len(port_system.nodes) == 6
        stats = snake.stats()
    assert ok == 200, stats
    assert stats["total_errors"] == 0
