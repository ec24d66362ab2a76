"""Seed-000 TDMA slots (CHAIN = 0): every board answers a query, whatever
the mask, TDMA_OFFSET + TDMA_SLOT x its physical ID clocks after it (150 +
256 x ID: about 3 us + 5.2 us per node), with an isochronous-style request."""

from __future__ import annotations

import cocotb

import packets as pk
from phy_model import REQ_ISO
from test_bus import PC, setup

# From the slot instant to the LREQ start bit (REQUEST_DELAY + 3 registers).
REQUEST_PIPELINE = 19


@cocotb.test()
async def tdma_slots_by_physical_id(dut):
    bus = await setup(dut)
    await bus.request(pk.write_quadlet(pk.node_id(0), PC, 0x1800, 0x00070002, tl=1))
    await bus.settle(400)
    query = dut.n[0].node.hub.query_at.value.to_unsigned()   # the query's packet clock
    for phy_id, phy in enumerate(bus.phys):
        reqs = [r for r in phy.requests if r.kind == REQ_ISO]
        assert len(reqs) == 1, f"node {phy_id}: {len(reqs)} requests"
        assert reqs[0].start == query + 150 + 256 * phy_id + REQUEST_PIPELINE
    broadcasts = [e for e in bus.log if e[2] == "iso"]
    assert [e[1] for e in broadcasts] == [0, 1, 2]
    for (_, node, _, packets) in broadcasts:
        assert pk.decode(packets[0]).words[0] == 0x00070021
