"""Test harness for one firelink_node: clock, reset, the PHY model, a host
that sends requests and collects the node's acks and responses, and the
QLA inputs."""

from __future__ import annotations

import cocotb
from cocotb.clock import Clock
from cocotb.triggers import FallingEdge, RisingEdge

import packets as pk
from phy_model import S400, Phy, board_phy_registers, phy_of

CLOCK_PS = 20346          # 49.152 MHz (20.345 ns, rounded to an even ps)
HOST = pk.node_id(5)      # the PC's node ID in these tests


class Host:
    """Sends packets through the PHY model and returns what the node sent."""

    def __init__(self, dut, phy: Phy):
        self.dut = dut
        self.phy = phy

    async def clocks(self, n: int) -> None:
        for _ in range(n):
            await FallingEdge(self.dut.clk)

    async def send(self, packet: bytes, speed: int = S400, wait: int = 400):
        """Send one packet; return the node's transmission that follows (ack
        and concatenated response), or None if none came within `wait`
        clocks after the packet ended."""
        before = len(self.phy.transmissions)
        self.phy.receive(packet, speed)
        while self.phy.drive:
            await FallingEdge(self.dut.clk)
        for _ in range(wait):
            await FallingEdge(self.dut.clk)
            if len(self.phy.transmissions) > before:
                return self.phy.transmissions[before]
            if self.phy._tx is not None:
                continue
        return None

    async def request(self, packet: bytes, speed: int = S400):
        """A unicast request: returns (ack code, decoded response or None)."""
        tx = await self.send(packet, speed)
        assert tx is not None, "no ack"
        assert tx.packets, "granted, but nothing sent"
        ack = tx.packets[0]
        assert len(ack) == 1 and (ack[0] >> 4) == (~ack[0] & 0xF), f"bad ack byte {ack.hex()}"
        response = pk.decode(tx.packets[1]) if len(tx.packets) > 1 else None
        if response is not None:
            assert response.header_crc_ok, "response header CRC"
            assert response.data_crc_ok in (None, True), "response data CRC"
        return ack[0] >> 4, response

    async def read(self, node: int, offset: int, tl: int = 1) -> int:
        ack, resp = await self.request(pk.read_quadlet(node, HOST, offset, tl))
        assert ack == pk.ACK_PENDING and resp is not None
        assert resp.tcode == pk.TC_READ_QUADLET_RESPONSE and resp.tl == tl
        assert resp.dest == HOST and resp.rcode == pk.RCODE_COMPLETE
        return resp.q3

    async def write(self, node: int, offset: int, value: int, tl: int = 2) -> None:
        ack, resp = await self.request(pk.write_quadlet(node, HOST, offset, value, tl))
        assert ack == pk.ACK_COMPLETE and resp is None

    async def read_block(self, node: int, offset: int, quadlets: int, tl: int = 3) -> list[int]:
        ack, resp = await self.request(pk.read_block(node, HOST, offset, 4 * quadlets, tl))
        assert ack == pk.ACK_PENDING and resp is not None
        assert resp.tcode == pk.TC_READ_BLOCK_RESPONSE and resp.rcode == pk.RCODE_COMPLETE
        assert resp.data_length == 4 * quadlets
        return resp.words


def set_inputs(dut, **kw) -> None:
    """Drive the QLA inputs (defaults: everything 0, supply present)."""
    def pack(values, bits=32):
        v = 0
        for i, x in enumerate(values):
            v |= (x & ((1 << bits) - 1)) << (bits * i)
        return v
    dut.adc.value = pack(kw.get("adc", [0] * 4))
    dut.enc_raw.value = pack(kw.get("enc_raw", [0] * 4))
    dut.enc_period.value = pack(kw.get("enc_period", [0] * 4))
    dut.enc_qtr1.value = pack(kw.get("enc_qtr1", [0] * 4))
    dut.enc_qtr5.value = pack(kw.get("enc_qtr5", [0] * 4))
    dut.enc_run.value = pack(kw.get("enc_run", [0] * 4))
    for name in ("enc_a", "enc_b", "enc_index", "neg_limit", "pos_limit", "home"):
        getattr(dut, name).value = kw.get(name, 0)
    dut.temperature.value = kw.get("temperature", 0)
    dut.supply_present.value = kw.get("supply_present", 1)
    dut.supply_good.value = kw.get("supply_good", 0)


async def start(dut, phy_id: int = 1, **inputs):
    """Clock, inputs, reset, PHY model, bus reset giving `phy_id`."""
    set_inputs(dut, **inputs)
    dut.phy_ctl_i.value = 0
    dut.phy_d_i.value = 0
    cocotb.start_soon(Clock(dut.clk, CLOCK_PS, unit="ps", impl="gpi").start())
    dut.rst.value = 1
    for _ in range(4):
        await RisingEdge(dut.clk)
    dut.rst.value = 0
    phy = phy_of(dut, regs=board_phy_registers(phy_id))
    cocotb.start_soon(phy.run())
    phy.bus_reset(phy_id)
    host = Host(dut, phy)
    for _ in range(400):
        await FallingEdge(dut.clk)
        if int(dut.phy_id_valid.value) and not phy.drive:
            break
    assert int(dut.phy_id_valid.value) == 1 and int(dut.phy_id.value) == phy_id
    return phy, host
