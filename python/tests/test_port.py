"""Ports, discovery and register access."""

import pytest

import firelink

HW_VERSION = 4
FW_VERSION = 7
WATCHDOG = 3
QLA1 = 0x514C4131


def test_sim_port_scans_eight_rev8_boards():
    port = firelink.open("sim")
    boards = port.scan()
    assert [b.board_id for b in boards] == list(range(8))
    assert {b.firmware for b in boards} == {8}
    assert {b.hardware for b in boards} == {"QLA1"}
    assert all(b.axes == 4 for b in boards)
    assert "Board(board_id=0" in repr(boards[0])


@pytest.mark.parametrize("spec,count,firmware", [("sim:2", 2, 8), ("sim:3:7", 3, 7), ("sim:1:8", 1, 8)])
def test_sim_port_descriptions(spec, count, firmware):
    boards = firelink.open(spec).scan()
    assert len(boards) == count
    assert {b.firmware for b in boards} == {firmware}


def test_registers_read_and_write():
    port = firelink.open("sim:2")
    node = port.scan()[1].node
    assert port.read_quadlet(node, HW_VERSION) == QLA1
    assert port.read_quadlet(node, FW_VERSION) == 8
    port.write_quadlet(node, WATCHDOG, 1234)
    assert port.read_quadlet(node, WATCHDOG) & 0xFFFF == 1234
    # A block read at address 0 is the real-time read block: the timestamp,
    # then the status register (quadlet register 0).
    block = port.read_block(node, 0, 4)
    assert isinstance(block, bytes) and len(block) == 16
    assert int.from_bytes(block[4:8], "big") == port.read_quadlet(node, 0)


def test_virtual_time_advances_only_when_asked():
    port = firelink.open("sim:1")
    t0 = port.now
    port.wait(0.25)
    assert port.now == pytest.approx(t0 + 0.25, abs=1e-6)


@pytest.mark.parametrize(
    "spec",
    ["nowhere", "sim:0", "sim:17", "sim:x", "sim:8:10", "sim:8:8:extra", "udp:not a host:99999"],
)
def test_bad_port_descriptions_raise_port_error(spec):
    with pytest.raises(firelink.PortError):
        firelink.open(spec)


def test_a_port_description_must_be_a_string():
    with pytest.raises(firelink.PortError):
        firelink.open(8)  # type: ignore[arg-type]
    with pytest.raises(firelink.PortError, match="not int"):
        firelink.Port(8)  # type: ignore[arg-type]


def test_bad_arguments_raise_the_documented_errors():
    port = firelink.open("sim:1")
    with pytest.raises(firelink.InvalidRequest, match="node 64"):
        port.read_quadlet(64, 0)
    with pytest.raises(firelink.InvalidRequest, match="0xFFFFFFFFFFFF"):
        port.read_quadlet(0, 1 << 48)
    with pytest.raises(firelink.InvalidRequest, match="1 to 512"):
        port.read_block(0, 0, 0)
    with pytest.raises(firelink.InvalidRequest, match="whole quadlets"):
        port.write_block(0, 0, b"abc")
    with pytest.raises(firelink.InvalidRequest, match="from 0 to 86400 s"):
        port.wait(-1.0)
    with pytest.raises(firelink.InvalidRequest, match="node must be an integer from 0 to 63, not str"):
        port.read_quadlet("zero", 0)  # type: ignore[arg-type]
    with pytest.raises(firelink.InvalidRequest, match="node -1 is out of range"):
        port.read_quadlet(-1, 0)
    with pytest.raises(firelink.InvalidRequest, match="data must be bytes"):
        port.write_block(0, 0, "abcd")  # type: ignore[arg-type]
    port.write_block(0, 0x1000, bytearray(4))  # bytearray and memoryview are bytes too
    port.write_block(0, 0x1000, memoryview(b"\0\0\0\1"))


def test_a_silent_node_times_out():
    port = firelink.open("sim:1")
    with pytest.raises(firelink.BusTimeout):
        port.read_quadlet(40, FW_VERSION)


def test_a_port_given_to_an_io_system_is_no_longer_usable():
    port = firelink.open("sim:2")
    io = firelink.IoSystem(port)
    assert len(io.boards) == 2
    with pytest.raises(firelink.PortError, match="IoSystem"):
        port.scan()
    with pytest.raises(firelink.PortError, match="already used"):
        firelink.IoSystem(port)
