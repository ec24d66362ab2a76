"""board_watchdog (power-up period 4 ticks for the test): fires exactly
256 x period clocks after the last write (judged EVAL_DELAY clocks late, a
write later than the expiry instant finds it fired), refreshed by writes,
off with period 0, cleared by `clear`, back to power-up on reboot."""

from __future__ import annotations

import cocotb
from cocotb.clock import Clock
from cocotb.triggers import FallingEdge, RisingEdge

from harness import CLOCK_PS


async def tick(dut, n=1):
    for _ in range(n):
        await FallingEdge(dut.clk)
        dut.now.value = (int(dut.now.value) + 1) & 0xFFFFFFFF


async def start(dut):
    cocotb.start_soon(Clock(dut.clk, CLOCK_PS, unit="ps", impl="gpi").start())
    for name in ("refresh", "set_period", "clear", "reboot"):
        getattr(dut, name).value = 0
    dut.refresh_time.value = 0
    dut.period_in.value = 0
    dut.now.value = 0
    dut.rst.value = 1
    await RisingEdge(dut.clk)
    await RisingEdge(dut.clk)
    dut.rst.value = 0
    await FallingEdge(dut.clk)


async def fire_time(dut, limit=5000):
    for _ in range(limit):
        await tick(dut)
        if int(dut.fire.value):
            return int(dut.now.value)
    return None


@cocotb.test()
async def fires_at_the_exact_clock(dut):
    await start(dut)
    assert int(dut.period.value) == 4
    # Power-up: expiry at clock 1024, judged 4 clocks later.
    t = await fire_time(dut)
    assert int(dut.timed_out.value) == 1
    fired = t            # `now` when the pulse is seen, for a write at 0
    assert fired == 1024 + 4, fired   # judged EVAL_DELAY (4) clocks late
    # The host enables an amplifier (a write: refresh and clear together).
    # Being later than the expiry, the write finds the watchdog fired
    # (one more pulse), then clears it.
    w = int(dut.now.value)
    dut.refresh.value = 1
    dut.refresh_time.value = w
    dut.clear.value = 1
    await tick(dut)
    dut.refresh.value = 0
    dut.clear.value = 0
    assert int(dut.timed_out.value) == 0
    # It fires again 1024 clocks after that write, at the same offset.
    t = await fire_time(dut)
    assert t - w == fired, (t, w, fired)
    # Period 0: never.
    dut.clear.value = 1
    dut.set_period.value = 1
    dut.period_in.value = 0
    await tick(dut)
    dut.clear.value = 0
    dut.set_period.value = 0
    assert await fire_time(dut, 3000) is None


@cocotb.test()
async def a_write_after_the_expiry_instant_finds_it_fired(dut):
    await start(dut)
    await tick(dut, 1020)
    # A write stamped 1025 (after the 1024 expiry) arriving before the
    # judged time: the watchdog fires first.
    dut.refresh.value = 1
    dut.refresh_time.value = 1025
    await tick(dut)
    dut.refresh.value = 0
    assert int(dut.timed_out.value) == 1
