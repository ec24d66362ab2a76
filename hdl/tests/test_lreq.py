"""phy_lreq_tx: the serial LREQ frames (start bit, type, fields, stop bit,
most significant bit first), one request at a time, ready only when the
line is free."""

from __future__ import annotations

import cocotb
from cocotb.clock import Clock
from cocotb.triggers import FallingEdge, RisingEdge

from harness import CLOCK_PS


async def frame(dut, kind, speed=0, addr=0, data=0) -> list[int]:
    while not int(dut.req_ready.value):
        await FallingEdge(dut.clk)
    dut.req_valid.value = 1
    dut.req_type.value = kind
    dut.req_speed.value = speed
    dut.req_addr.value = addr
    dut.req_data.value = data
    await FallingEdge(dut.clk)
    dut.req_valid.value = 0
    bits = []
    for _ in range(20):
        bits.append(int(dut.lreq.value))
        await FallingEdge(dut.clk)
    while bits and bits[-1] == 0:
        bits.pop()
    return bits


@cocotb.test()
async def request_frames(dut):
    cocotb.start_soon(Clock(dut.clk, CLOCK_PS, unit="ps", impl="gpi").start())
    dut.req_valid.value = 0
    dut.rst.value = 1
    await RisingEdge(dut.clk)
    await RisingEdge(dut.clk)
    dut.rst.value = 0
    await FallingEdge(dut.clk)
    assert int(dut.lreq.value) == 0
    # Isochronous request at S400: 1 001 100 0.
    assert await frame(dut, 1, speed=0b100) == [1, 0, 0, 1, 1]
    # Immediate at S100: 1 000 000 0 (only the start bit is high).
    assert await frame(dut, 0, speed=0) == [1]
    # Fair at S200: 1 011 010 0.
    assert await frame(dut, 3, speed=0b010) == [1, 0, 1, 1, 0, 1]
    # Register read of 0xA: 1 100 1010 0.
    assert await frame(dut, 4, addr=0xA) == [1, 1, 0, 0, 1, 0, 1]
    # Register write of 0x5A to 1: 1 101 0001 01011010 0.
    assert await frame(dut, 5, addr=1, data=0x5A) == [1, 1, 0, 1, 0, 0, 0, 1, 0, 1, 0, 1, 1, 0, 1]
    # Not ready while a frame is on the line.
    dut.req_valid.value = 1
    dut.req_type.value = 5
    await FallingEdge(dut.clk)
    dut.req_valid.value = 0
    busy = 0
    for _ in range(18):
        busy += 1 - int(dut.req_ready.value)
        await FallingEdge(dut.clk)
    assert busy == 16
