"""Several HDL nodes on one modelled bus: three firelink_node boards (board
IDs 1, 2, 3 at physical IDs 0, 1, 2) and the PC at the root (physical ID 3).

The bus model repeats every packet a node sends to every other node (and
to the PC), arbitrates the nodes' requests (immediate grants for acks,
isochronous-style requests after two idle clocks, one owner at a time) and
lets the PC send when the bus is quiet. A broadcast cycle runs as in seed
000: query, chained status broadcasts, hub read from one board, command
block; then the chain's time-out for a board that does not answer."""

from __future__ import annotations

import cocotb
from cocotb.clock import Clock
from cocotb.triggers import FallingEdge, RisingEdge

import packets as pk
from harness import CLOCK_PS
from phy_model import REQ_IMM, REQ_ISO, S400, Phy, board_phy_registers

PC = pk.node_id(3)


class Bus:
    def __init__(self, dut, count: int):
        self.dut = dut
        self.phys: list[Phy] = []
        self.pc_received: list[tuple[int, bytes]] = []
        self.log: list[tuple[int, int, str, list]] = []   # (granted, node, kind, packets)
        self.owner = None
        self.quiet = 0
        for i in range(count):
            n = dut.n[i]
            phy = Phy(dut.clk, n.ctl_i, n.d_i, n.ctl_o, n.d_o, n.oe, n.lreq, n.now,
                      regs=board_phy_registers(i), name=f"phy{i}")
            phy.clock_ps = CLOCK_PS
            phy.grant_policy = self._policy(i)
            phy.on_transmission = self._delivered(i)
            self.phys.append(phy)

    def busy(self) -> bool:
        return self.owner is not None or any(p.drive or p._tx is not None for p in self.phys)

    def _policy(self, i):
        def policy(phy, now):
            req = phy.bus_request
            if self.owner is not None:
                return False
            if req.kind == REQ_IMM or (req.kind == REQ_ISO and self.quiet >= 2):
                self.owner = i
                return True
            return False
        return policy

    def _delivered(self, i):
        def deliver(phy, tx):
            self.owner = None
            kind = tx.request.name if tx.request else "?"
            self.log.append((tx.granted, i, kind, tx.packets))
            for packet in tx.packets:
                self.pc_received.append((tx.end, packet))
                if len(packet) >= 4:
                    for j, other in enumerate(self.phys):
                        if j != i:
                            other.receive(packet, S400)
        return deliver

    async def watch(self):
        while True:
            await FallingEdge(self.dut.clk)
            self.quiet = 0 if self.busy() else self.quiet + 1

    async def send(self, packet: bytes, gap: int = 20) -> None:
        """The PC sends a packet once the bus has been quiet for `gap` clocks."""
        while self.quiet < gap or any(p.bus_request for p in self.phys):
            await FallingEdge(self.dut.clk)
        before = len(self.pc_received)
        for phy in self.phys:
            phy.receive(packet, S400)
        self.owner = "pc"
        while any(p.drive for p in self.phys):
            await FallingEdge(self.dut.clk)
        self.owner = None
        return before

    async def request(self, packet: bytes):
        """A unicast from the PC: returns the responder's packets."""
        before = len(self.log)
        await self.send(packet)
        for _ in range(600):
            await FallingEdge(self.dut.clk)
            if len(self.log) > before and self.log[-1][2] == "imm":
                return self.log[-1][3]
        raise AssertionError("no answer")

    async def settle(self, clocks: int = 200):
        while True:
            await FallingEdge(self.dut.clk)
            if self.quiet >= clocks and not any(p.bus_request for p in self.phys):
                return


async def setup(dut):
    cocotb.start_soon(Clock(dut.clk, CLOCK_PS, unit="ps", impl="gpi").start())
    for i in range(3):
        dut.n[i].ctl_i.value = 0
        dut.n[i].d_i.value = 0
        dut.n[i].adc.value = sum(((0x1000 * (i + 1) + a) & 0xFFFFFFFF) << (32 * a) for a in range(4))
    dut.rst.value = 1
    for _ in range(4):
        await RisingEdge(dut.clk)
    dut.rst.value = 0
    bus = Bus(dut, 3)
    for i, phy in enumerate(bus.phys):
        cocotb.start_soon(phy.run())
        phy.bus_reset(i)
    cocotb.start_soon(bus.watch())
    await bus.settle(50)
    for i in range(3):
        assert int(dut.n[i].phy_id_valid.value) and int(dut.n[i].phy_id.value) == i
    return bus


def hub_entries(words: list[int], count: int):
    return [words[33 * k:33 * (k + 1)] for k in range(count)], words[33 * count]


@cocotb.test()
async def broadcast_cycle_on_one_bus(dut):
    bus = await setup(dut)
    # Query to node 0 (board 1 acks it, the others snoop): seq 0x0102, boards 1-3.
    start = len(bus.log)
    answer = await bus.request(pk.write_quadlet(pk.node_id(0), PC, 0x1800, 0x0102000E, tl=1))
    assert answer == [bytes([pk.ack_byte(pk.ACK_COMPLETE)])]
    await bus.settle()
    broadcasts = [e for e in bus.log[start:] if e[2] == "iso"]
    assert [e[1] for e in broadcasts] == [0, 1, 2], "chained in board order"
    for (granted, node, _, packets) in broadcasts:
        p = pk.decode(packets[0])
        assert p.header_crc_ok and p.data_crc_ok and p.dest == 0xFFFF and p.pri == 0xA
        assert p.words[0] == 0x01020021 and (p.words[2] >> 24) & 0xF == node + 1
        assert p.words[5] == 0x1000 * (node + 1)                       # its own ADC word
    # Each board's request followed the previous board's packet (chain).
    reqs = [[r for r in phy.requests if r.kind == REQ_ISO][-1] for phy in bus.phys]
    assert reqs[0].start < reqs[1].start < reqs[2].start
    # Every board holds every entry: read the hub from board 3.
    packets = await bus.request(pk.read_block(pk.node_id(2), PC, 0x1000, 4 * 100, tl=2))
    resp = pk.decode(packets[1])
    assert resp.rcode == 0 and resp.data_crc_ok
    entries, timing = hub_entries(resp.words, 3)
    for k, e in enumerate(entries):
        assert e[0] >> 24 == 33 and (e[0] >> 16) & 0xFF == 0x02 and not e[0] & 0x8000
        assert (e[2] >> 24) & 0xF == k + 1
    assert (timing & 0xFFFF) == (timing >> 16) + 4 * (5 + 99)
    # And board 1 holds the same blocks (its own entry stored from its snapshot).
    packets = await bus.request(pk.read_block(pk.node_id(0), PC, 0x1000, 4 * 99, tl=3))
    other = pk.decode(packets[1]).words
    assert [e[1:] for e in hub_entries(other + [0], 3)[0]] == [e[1:] for e in entries]
    # Command block to node 63 at offset 0: each board takes its slice.
    block = b""
    for board in (1, 2, 3):
        block += pk.to_bytes([(board << 8) | 6] + [0x80000000 | (0x7000 + board * 16 + a)
                                                   for a in range(4)] + [0])
    await bus.send(pk.write_block(0xFFFF, PC, 0, block))
    await bus.settle(50)
    for node in range(3):
        packets = await bus.request(pk.read_quadlet(pk.node_id(node), PC, 0x0021, tl=4))
        assert pk.decode(packets[1]).q3 == 0x7000 + (node + 1) * 16 + 1
        assert (int(dut.n[node].dac_out.value) >> 16) & 0xFFFF == 0x7000 + (node + 1) * 16 + 1


@cocotb.test()
async def chain_goes_on_without_a_silent_board(dut):
    bus = await setup(dut)
    # Board 0 is selected but absent: board 1 waits for it, then gives up
    # 2458 clocks (about 50 us) after its first slot.
    await bus.request(pk.write_quadlet(pk.node_id(0), PC, 0x1800, 0x0203000F, tl=1))
    query_end = int(dut.n[0].now.value)
    await bus.settle(3000)
    reqs = [[r for r in phy.requests if r.kind == REQ_ISO] for phy in bus.phys]
    assert all(len(r) == 1 for r in reqs)
    first = reqs[0][0].start
    assert 150 + 2458 <= first - query_end < 150 + 2458 + 200
    assert reqs[1][0].start > first and reqs[2][0].start > reqs[1][0].start
    # The hub records all three, with the query's sequence.
    packets = await bus.request(pk.read_block(pk.node_id(1), PC, 0x1000, 4 * 100, tl=2))
    entries, _ = hub_entries(pk.decode(packets[1]).words, 3)
    assert [(e[2] >> 24) & 0xF for e in entries] == [1, 2, 3]
    assert all((e[0] >> 16) & 0xFF == 0x03 for e in entries)
