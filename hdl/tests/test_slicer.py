"""command_slicer (BOARD_ID 2): finds its block in a command block and
writes its DAC words and control word (bits 19:0 only); malformed walks
change nothing."""

from __future__ import annotations

import cocotb
from cocotb.clock import Clock
from cocotb.triggers import FallingEdge, RisingEdge

from harness import CLOCK_PS


def block(board, dacs, control, quads=6):
    return [(board << 8) | quads] + dacs + [control]


async def slice_of(dut, words: list[int], length: int | None = None) -> list[tuple[int, int]]:
    length = 4 * len(words) if length is None else length
    dut.length.value = length
    dut.time_in.value = 1234
    dut.start.value = 1
    await FallingEdge(dut.clk)
    dut.start.value = 0
    writes = []
    # The receive buffer: a quadlet two clocks after its address (the
    # block RAM's read register and its output register).
    addrs = [0, 0]
    for _ in range(400):
        dut.rd_data.value = words[addrs[0]] if addrs[0] < len(words) else 0
        addrs = [addrs[1], int(dut.rd_addr.value)]
        await FallingEdge(dut.clk)
        if int(dut.wr_en.value):
            assert int(dut.wr_time.value) == 1234
            writes.append((int(dut.wr_addr.value), int(dut.wr_data.value)))
        if not int(dut.busy.value) and _ > 3:
            break
    return writes


@cocotb.test()
async def takes_its_slice(dut):
    cocotb.start_soon(Clock(dut.clk, CLOCK_PS, unit="ps", impl="gpi").start())
    dut.start.value = 0
    dut.rd_data.value = 0
    dut.rst.value = 1
    await RisingEdge(dut.clk)
    await RisingEdge(dut.clk)
    dut.rst.value = 0
    await FallingEdge(dut.clk)
    ours = [0x80001111, 0x80002222, 0x80003333, 0x80004444]
    words = block(1, [0x80000001] * 4, 0) + block(2, ours, 0x00FC0F0F) + block(3, [0] * 4, 0)
    writes = await slice_of(dut, words)
    assert writes == [(0x11, ours[0]), (0x21, ours[1]), (0x31, ours[2]), (0x41, ours[3]),
                      (0x00, 0x000C0F0F)]
    # Not addressed.
    assert await slice_of(dut, block(1, [0] * 4, 0) + block(3, [0] * 4, 0)) == []
    # A zero-length header before ours: the walk stops.
    assert await slice_of(dut, [0x00000100] + block(2, ours, 0)) == []
    # Ours is not 6 quadlets.
    assert await slice_of(dut, block(2, ours + [0], 0, quads=7)) == []
    # A block running past the payload.
    assert await slice_of(dut, block(1, [0] * 4, 0, quads=9) + block(2, ours, 0)) == []
    # Not whole quadlets.
    assert await slice_of(dut, block(2, ours, 0), length=23) == []
    # Ours alone, unicast.
    assert len(await slice_of(dut, block(2, ours, 0))) == 5
