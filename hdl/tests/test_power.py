"""board_power with short times (hold 1000 clocks, mismatch 20000 clocks):
power and amplifier requests, the exact turn-on instant max(request,
supply good + hold) + delay x 1024, the watchdog dropping requests, and
the current check tripping an axis whose current stays away from its
command (checked at 100 us ticks and at turn-on)."""

from __future__ import annotations

import cocotb
from cocotb.clock import Clock
from cocotb.triggers import FallingEdge, ReadOnly, RisingEdge, Timer

from harness import CLOCK_PS

HOLD = 1000
MISMATCH = 20000


CLOCK = {"now": 0}     # the `now` the next rising edge sees


async def tick(dut, n=1):
    for _ in range(n):
        await FallingEdge(dut.clk)
        CLOCK["now"] += 1
        dut.now.value = CLOCK["now"]
        for name in ("cmd_valid", "amp_req_valid", "watchdog_fire"):
            getattr(dut, name).value = 0


async def settled(dut):
    """Outputs as they are for the current `now` (then back to a writable step)."""
    await ReadOnly()
    values = (int(dut.amp_on.value), int(dut.requested.value), int(dut.safety_disabled.value))
    await Timer(1, "ps")
    return values


async def command(dut, word):
    dut.cmd_valid.value = 1
    dut.cmd_word.value = word
    dut.cmd_time.value = CLOCK["now"]
    await tick(dut)


async def start(dut, delay_units=1):
    cocotb.start_soon(Clock(dut.clk, CLOCK_PS, unit="ps", impl="gpi").start())
    for name in ("cmd_valid", "amp_req_valid", "amp_req_value", "watchdog_fire", "reboot",
                 "delay_written", "supply_good"):
        getattr(dut, name).value = 0
    dut.supply_present.value = 1
    dut.check_enable.value = 0xF
    dut.cmd_word.value = 0
    dut.cmd_time.value = 0
    dut.amp_req_time.value = 0
    dut.enable_delay.value = int.from_bytes(bytes([delay_units] * 4), "little")
    dut.measured.value = int.from_bytes((0x8000).to_bytes(2, "little") * 4, "little")
    dut.command.value = int.from_bytes((0x8000).to_bytes(2, "little") * 4, "little")
    dut.now.value = 0
    CLOCK["now"] = 0
    dut.rst.value = 1
    await RisingEdge(dut.clk)
    await RisingEdge(dut.clk)
    dut.rst.value = 0
    await FallingEdge(dut.clk)


async def amp_on_clock(dut, axis, limit=20000):
    for _ in range(limit):
        on, _, _ = await settled(dut)
        if (on >> axis) & 1:
            return CLOCK["now"]
        await tick(dut)
    return None


@cocotb.test()
async def turn_on_instant_is_exact(dut):
    await start(dut, delay_units=1)
    await tick(dut, 10)
    await command(dut, 0x000C0000)                 # power on
    assert int(dut.power_enabled.value) == 1
    await tick(dut, 20)
    good = CLOCK["now"]
    dut.supply_good.value = 1                      # seen at the next edge, clock `good`
    await tick(dut, 100)
    req = CLOCK["now"]
    await command(dut, 0x00000101)                 # amplifier 1 (axis 0)
    assert (await settled(dut))[1] & 1
    on = await amp_on_clock(dut, 0)
    assert on == max(req, good + HOLD) + 1024, (on, req, good)
    # A request made after the hold: max() picks the request.
    await tick(dut, 10)
    req = CLOCK["now"]
    await command(dut, 0x00000202)                 # amplifier 2 (axis 1)
    assert await amp_on_clock(dut, 1) == req + 1024
    # The watchdog drops every request; power stays.
    dut.watchdog_fire.value = 1
    await tick(dut, 2)
    on, requested, _ = await settled(dut)
    assert requested == 0 and on == 0
    assert int(dut.power_enabled.value) == 1


@cocotb.test()
async def current_mismatch_trips_the_axis(dut):
    await start(dut, delay_units=0)
    await command(dut, 0x000C0000)
    dut.supply_good.value = 1
    await tick(dut, 2)
    await command(dut, 0x00000101)
    on = await amp_on_clock(dut, 0)
    assert on is not None
    # Commanded 0xC000, measured 0x8000: 0x4000 counts apart, far above 2306.
    dut.command.value = int.from_bytes((0xC000).to_bytes(2, "little") + (0x8000).to_bytes(2, "little") * 3, "little")
    tripped = None
    for _ in range(MISMATCH + 3 * 4916):
        await tick(dut)
        if int(dut.safety_disabled.value) & 1:
            tripped = CLOCK["now"]
            break
    assert tripped is not None, "no trip"
    amp, requested, _ = await settled(dut)
    assert requested & 1 == 0 and amp & 1 == 0
    # The check ran at turn-on (mismatch from then on), so it trips at the
    # first 100 us tick at least MISMATCH clocks after it.
    assert MISMATCH <= tripped - on <= MISMATCH + 4916 + 8, tripped - on
    # Asking for the amplifier again clears the safety disable.
    await command(dut, 0x00000101)
    _, requested, disabled = await settled(dut)
    assert disabled & 1 == 0 and requested & 1
