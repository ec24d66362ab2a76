"""Whole-node tests of firelink_node (BOARD_ID 3) against the behavioural
PHY: reads and writes at every receive speed, the real-time blocks, acks,
CRC errors, PHY register access, the watchdog and the broadcast cycle."""

from __future__ import annotations

import cocotb

import packets as pk
from harness import HOST, start
from phy_model import REQ_IMM, S100, S200, S400

NODE = pk.node_id(1)


@cocotb.test()
async def quadlet_reads_at_every_speed(dut):
    phy, host = await start(dut, phy_id=1)
    for speed in (S100, S200, S400):
        assert await host.read(NODE, 7, tl=10 + speed) == 8            # FW_VERSION
        assert await host.read(NODE, 4) == 0x514C4131                   # "QLA1"
        status = await host.read(NODE, 0)
        assert (status >> 28) == 4 and ((status >> 24) & 0xF) == 3     # axes, board ID
    # The ack was asked for with an immediate request during the packet.
    assert any(r.kind == REQ_IMM for r in phy.requests)
    assert not phy.errors
