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


@cocotb.test()
async def quadlet_writes_and_registers(dut):
    phy, host = await start(dut, phy_id=1)
    await host.write(NODE, 3, 0x1234)                       # WATCHDOG period
    assert await host.read(NODE, 3) == 0x1234
    await host.write(NODE, 6, 0x0F0A)                       # DIGITAL_OUT: mask F, raw bits
    assert await host.read(NODE, 6) == 0x0A                 # stored as written (the host inverts)
    assert (await host.read(NODE, 10) >> 12) & 0xF == 0xA  # DIGITAL_IN echoes them
    assert await host.read(NODE, 11) == 0xFFFFFFFF          # IP_UNASSIGNED (EthernetIO.v)
    await host.write(NODE, 11, 0x6400FEA9)                  # IP_ADDR
    assert await host.read(NODE, 11) == 0x6400FEA9
    await host.write(NODE, 0x0014, 0x00123456)              # axis 1 ENC_PRELOAD
    assert await host.read(NODE, 0x0014) == 0x00123456
    assert await host.read(NODE, 0x0015) & 0xFFFFFF == 0x123456
    await host.write(NODE, 0x0021, 0x80009000)              # axis 2 DAC, valid
    assert await host.read(NODE, 0x0021) == 0x9000
    await host.write(NODE, 0x0031, 0x00001111)              # not valid: ignored
    assert await host.read(NODE, 0x0031) == 0x8000
    # MOTOR_CONFIG powers up 0x03780418; bits 25/24 load delay and limit,
    # bits 31/30 are stored (MotorChannelQLA.v l.61, l.79, l.196-199).
    assert await host.read(NODE, 0x002B) == 0x03780418
    await host.write(NODE, 0x002B, 0x00100400)              # no load bit: kept
    assert await host.read(NODE, 0x002B) == 0x03780418
    await host.write(NODE, 0x002B, 0xC3108400)              # both, limit bit 15 dropped
    assert await host.read(NODE, 0x002B) == 0xC3100400
    assert (int(dut.dac_out.value) >> 16) & 0xFFFF == 0x9000    # the limit is no clamp
    await host.write(NODE, 0x0021, 0x80000000)
    assert (int(dut.dac_out.value) >> 16) & 0xFFFF == 0x0000
    # MOTOR_STATUS: current control (bit 20); a mode-1 command is taken
    # (control mode in 27:24, bit 20 clear); mode 2 is refused.
    assert await host.read(NODE, 0x002C) == 0x00100000
    await host.write(NODE, 0x0021, 0x81001234)
    assert await host.read(NODE, 0x002C) == 0x01001234
    await host.write(NODE, 0x0021, 0x82005678)
    assert await host.read(NODE, 0x002C) == 0x01001234
    # WATCHDOG keeps bit 31; PHY_DATA takes 16 host bits (BoardRegs.v).
    await host.write(NODE, 3, 0xFFFFFFFF)
    assert await host.read(NODE, 3) == 0x8000FFFF
    await host.write(NODE, 3, 0x00001680)
    await host.write(NODE, 2, 0xFFFFFFFF)
    assert await host.read(NODE, 2) == 0x0000FFFF
    assert await host.read(NODE, 0x2000) == 0               # unmapped
    assert await host.read(NODE, 15) == 0                   # GIT_DESC: Rev 9 on


@cocotb.test()
async def power_relay_and_amplifiers(dut):
    phy, host = await start(dut, phy_id=1)
    await host.write(NODE, 0, 0x000C0000)                   # power on
    await host.write(NODE, 0, 0x00030000)                   # relay on
    await host.write(NODE, 0, 0x00000F05)                   # amps 1, 3 requested
    status = await host.read(NODE, 0)
    assert status & (1 << 18) and status & (1 << 16) and status & (1 << 17)
    assert status & 0xF == 0x5
    assert int(dut.power_enable.value) == 1 and int(dut.relay_on.value) == 1
    # Supply good now; the amplifiers drive 40 ms + 2.5 ms later (not yet).
    dut.supply_good.value = 1
    await host.clocks(10)
    assert int(dut.amp_enable.value) == 0
    mstat = await host.read(NODE, 0x001C)                   # axis 1 MOTOR_STATUS
    assert mstat & (1 << 28) and not mstat & (1 << 29)
    # Power off drops every request.
    await host.write(NODE, 0, 0x00080000)
    assert (await host.read(NODE, 0)) & 0xF == 0


@cocotb.test()
async def realtime_block_read(dut):
    adc = [0x11112222, 0x33334444, 0x55556666, 0x77778888]
    phy, host = await start(dut, phy_id=1, adc=adc, enc_raw=[0, 5, -3, 100],
                            enc_period=[1, 2, 3, 4], enc_qtr1=[5, 6, 7, 8],
                            enc_qtr5=[9, 10, 11, 12], enc_run=[13, 14, 15, 16],
                            temperature=0x2A2B, home=0x3, enc_a=0x1)
    block = await host.read_block(NODE, 0, 32)
    assert len(block) == 32, block
    dut._log.info("block %s", [hex(w) for w in block])
    assert block[0] > 0                                         # clocks since reset
    assert block[1] == await host.read(NODE, 0)                 # STATUS
    assert block[3] == 0x04002A2B                               # data buffer status (QLA.v)
    assert await host.read(NODE, 5) == 0x2A2B
    assert block[4:8] == adc
    # Encoders start at the neutral count whatever the raw counter says.
    assert [w & 0xFFFFFF for w in block[8:12]] == [0x800000] * 4
    assert block[8] >> 28 & 1 == 1                              # Rev 8: A line in bit 28
    assert block[12:16] == [1, 2, 3, 4] and block[24:28] == [13, 14, 15, 16]
    assert all(w & 0xFFFF == 0x8000 for w in block[28:32])      # MOTOR_STATUS commands
    # The timestamp counts clocks since the previous sample.
    await host.clocks(100)
    again = await host.read_block(NODE, 0, 32)
    assert 100 < again[0] < 2000


@cocotb.test()
async def realtime_write_and_command_block(dut):
    phy, host = await start(dut, phy_id=1)
    def block(board, dacs, control):
        words = [(board << 8) | 6] + dacs + [control]
        return pk.to_bytes(words)
    # A command block for boards 1, 3 and 5, broadcast: board 3 takes its slice.
    data = block(1, [0x80001111] * 4, 0) + block(3, [0x80004000, 0x80005000, 0x00006000, 0x80007000],
                                                  0x003C0000) + block(5, [0x80000001] * 4, 0)
    tx = await host.send(pk.write_block(0xFFFF, HOST, 0, data))
    assert tx is None                                           # broadcast: no ack
    assert await host.read(NODE, 0x0011) == 0x4000
    assert await host.read(NODE, 0x0021) == 0x5000
    assert await host.read(NODE, 0x0031) == 0x8000             # not valid
    assert await host.read(NODE, 0x0041) == 0x7000
    status = await host.read(NODE, 0)
    assert status & (1 << 18)                                   # control 0x003C0000: power on
    assert await host.read(NODE, 7) == 8                        # bits 21:20 ignored: no reboot
    # The snooped command block to node 0 at 0xFFFF_FFFF_0000.
    data = block(3, [0x80000123] * 4, 0)
    await host.send(pk.write_block(pk.node_id(0), HOST, 0xFFFFFFFF0000, data))
    assert await host.read(NODE, 0x0011) == 0x0123
    # A malformed walk (length 0 before our block) changes nothing.
    data = pk.to_bytes([0x00000100]) + block(3, [0x80000999] * 4, 0)
    await host.send(pk.write_block(0xFFFF, HOST, 0, data))
    assert await host.read(NODE, 0x0011) == 0x0123
    # Rev 8 amplifier enables in the DAC words (bit 29 mask, bit 28 value).
    await host.write(NODE, 0, 0x000C0000)
    data = block(3, [0xB0008000, 0x80008000, 0x80008000, 0x80008000], 0)
    ack, _ = await host.request(pk.write_block(NODE, HOST, 0, data))
    assert ack == pk.ACK_COMPLETE
    assert (await host.read(NODE, 0)) & 0xF == 0x1


@cocotb.test()
async def crc_errors_change_nothing(dut):
    phy, host = await start(dut, phy_id=1)
    # Bad header CRC: ack_data_error (FireWire.v l.1090), no effect.
    bad = bytearray(pk.write_quadlet(NODE, HOST, 3, 0x0042))
    bad[17] ^= 0x10
    ack, resp = await host.request(bytes(bad))
    assert ack == pk.ACK_DATA_ERROR and resp is None
    assert await host.read(NODE, 3) == 0x1680
    # Bad data CRC: ack_data_error, no effect (the write is not applied).
    data = pk.to_bytes([(3 << 8) | 6, 0x80000777, 0x80000777, 0x80000777, 0x80000777, 0])
    bad = bytearray(pk.write_block(NODE, HOST, 0, data))
    bad[-1] ^= 0x01
    ack, resp = await host.request(bytes(bad))
    assert ack == pk.ACK_DATA_ERROR and resp is None
    assert await host.read(NODE, 0x0011) == 0x8000
    # Bad data in the payload itself (CRC of the original): same.
    bad = bytearray(pk.write_block(NODE, HOST, 0, data))
    bad[24] ^= 0x80
    ack, _ = await host.request(bytes(bad))
    assert ack == pk.ACK_DATA_ERROR
    assert await host.read(NODE, 0x0011) == 0x8000
    # A broadcast with a bad data CRC: silent, no effect.
    bad = bytearray(pk.write_block(0xFFFF, HOST, 0, data))
    bad[-2] ^= 0x01
    assert await host.send(bytes(bad)) is None
    assert await host.read(NODE, 0x0011) == 0x8000
    # A register block write (WATCHDOG, HW_VERSION, TEMPERATURE, DIGITAL_OUT)
    # with a bad data CRC: not even its first register changes.
    regs = pk.to_bytes([0x0055, 0, 0, 0x0F00])
    bad = bytearray(pk.write_block(NODE, HOST, 3, regs))
    bad[-1] ^= 0x40
    ack, _ = await host.request(bytes(bad))
    assert ack == pk.ACK_DATA_ERROR
    assert await host.read(NODE, 3) == 0x1680 and await host.read(NODE, 6) == 0
    ack, _ = await host.request(pk.write_block(NODE, HOST, 3, regs))
    assert ack == pk.ACK_COMPLETE
    assert await host.read(NODE, 3) == 0x0055 and await host.read(NODE, 6) == 0x00
    # The same packets intact do take effect.
    ack, _ = await host.request(pk.write_block(NODE, HOST, 0, data))
    assert ack == pk.ACK_COMPLETE
    assert await host.read(NODE, 0x0011) == 0x0777


@cocotb.test()
async def acks_for_other_tcodes_and_errors(dut):
    phy, host = await start(dut, phy_id=1)
    # A lock request: no ack at all (FireWire.v l.893-919); the grant the
    # link asked for goes unused.
    tx = await host.send(pk.lock_request(NODE, HOST, 0, bytes(8)))
    assert tx is not None and tx.packets == []
    # A write response (a request the board never made): ack_complete.
    wresp = pk._with_crc([(NODE << 16) | (7 << 10) | (pk.TC_WRITE_RESPONSE << 4), HOST << 16, 0])
    ack, _ = await host.request(wresp)
    assert ack == pk.ACK_COMPLETE
    # Block read lengths: 0 -> type error, not whole quadlets -> type error,
    # over 2048 -> address error; no data. (The software board answers 0
    # and 6 complete with that many bytes, as FireWire.v l.1162 does, and
    # reads the real-time block for any main-space block read; this node
    # does not yet: ARCHITECTURE.md, the FPGA node in Verilog.)
    for length, rcode in ((0, pk.RCODE_TYPE_ERROR), (6, pk.RCODE_TYPE_ERROR),
                          (4096, pk.RCODE_ADDRESS_ERROR)):
        ack, resp = await host.request(pk.read_block(NODE, HOST, 0x10, length, tl=9))
        assert ack == pk.ACK_PENDING and resp.rcode == rcode and resp.data_length == 0
    # Reads to broadcast are not answered; reads to another node neither.
    assert await host.send(pk.read_quadlet(0xFFFF, HOST, 0)) is None
    assert await host.send(pk.read_quadlet(pk.node_id(2), HOST, 0)) is None
    # A register block read reads register by register.
    words = await host.read_block(NODE, 4, 4)
    assert words == [0x514C4131, 0, 0, 8]


@cocotb.test()
async def phy_register_access(dut):
    phy, host = await start(dut, phy_id=1)
    await host.write(NODE, 1, 1)                            # read PHY register 1
    await host.clocks(60)
    assert await host.read(NODE, 2) == 0x13F               # register 1: gap count 63
    await host.write(NODE, 1, 0x1000 | (1 << 8) | 0x05)     # write gap count 5
    await host.clocks(60)
    assert phy.regs[1] == 0x05
    await host.write(NODE, 1, 3)
    await host.clocks(60)
    assert await host.read(NODE, 2) == 0x34F
    await host.write(NODE, 1, 0)
    await host.clocks(60)
    assert await host.read(NODE, 2) == 0x004               # physical ID 1 in bits 7:2
    assert [r.name for r in phy.requests if r.name in ("rdreg", "wrreg")] == \
        ["rdreg", "wrreg", "rdreg", "rdreg"]
    # A second bus reset renumbers the node.
    phy.bus_reset(4)
    await host.clocks(200)
    assert int(dut.phy_id.value) == 4
    assert await host.read(pk.node_id(4), 7) == 8


@cocotb.test()
async def watchdog_turns_amplifiers_off(dut):
    phy, host = await start(dut, phy_id=1, supply_good=1)
    await host.write(NODE, 3, 2)                            # 2 ticks = 512 clocks
    await host.write(NODE, 0, 0x000C0F0F)                   # power + all amplifiers
    assert (await host.read(NODE, 0)) & 0x80000F == 0x00000F
    await host.clocks(600)
    status = await host.read(NODE, 0)
    assert status & (1 << 23) and status & 0xF == 0          # timed out, requests dropped
    assert status & (1 << 18)                               # power stays on
    # Enabling an amplifier clears the flag.
    await host.write(NODE, 0, 0x00000101)
    assert (await host.read(NODE, 0)) & 0x80000F == 0x000001


@cocotb.test()
async def broadcast_query_and_hub(dut):
    phy, host = await start(dut, phy_id=1, adc=[0xABCD0123] * 4)
    # Query snooped at node 0: seq 0x1234, boards 3 and 5.
    await host.send(pk.write_quadlet(pk.node_id(0), HOST, 0x1800, 0x12340028), wait=10)
    for _ in range(400):
        await host.clocks(1)
        if phy.transmissions and phy.transmissions[-1].request and \
                phy.transmissions[-1].request.name == "iso":
            break
    tx = phy.transmissions[-1]
    assert tx.request.name == "iso" and tx.request.speed == 0b100
    bc = pk.decode(tx.packets[0])
    assert bc.dest == 0xFFFF and bc.pri == 0xA and bc.tcode == pk.TC_WRITE_BLOCK
    assert bc.offset == 0xFFFFFF001000 and bc.data_length == 132 and bc.data_crc_ok
    w = bc.words
    assert w[0] == 0x12340021 and w[5] == 0xABCD0123 and (w[2] >> 24) & 0xF == 3
    # The query went out; the board's own entry is in its hub, header rewritten.
    assert await host.read(NODE, 0x1800) == 0x12340028
    hub = await host.read_block(NODE, 0x1000, 34)
    assert hub[0] >> 24 == 33 and (hub[0] >> 16) & 0xFF == 0x34 and not hub[0] & 0x8000
    assert hub[1:33] == w[1:33]
    assert await host.read(NODE, 0x1802) == 33
    # Board 5's broadcast arrives: stored, the cycle is complete: timing quadlet.
    other = [0x12340021] + [0] * 32
    other[2] = 5 << 24
    await host.send(pk.write_block(0xFFFF, pk.node_id(2), 0xFFFFFF001000, pk.to_bytes(other), pri=0xA))
    assert await host.read(NODE, 0x1802) == 67
    hub = await host.read_block(NODE, 0x1000, 67)
    assert hub[33] >> 24 == 33 and hub[35] == (5 << 24)
    start_clocks, now_clocks = hub[66] >> 16, hub[66] & 0xFFFF
    assert now_clocks == start_clocks + 4 * (5 + 66)
    # Sequence errors are flagged (Rev 8: low byte and error bit).
    other[0] = 0x12330021
    await host.send(pk.write_quadlet(pk.node_id(0), HOST, 0x1800, 0x12350020), wait=10)
    await host.send(pk.write_block(0xFFFF, pk.node_id(2), 0xFFFFFF001000, pk.to_bytes(other), pri=0xA))
    hub = await host.read_block(NODE, 0x1000, 2)
    assert hub[0] >> 24 == 33 and (hub[0] >> 16) & 0xFF == 0x33 and hub[0] & 0x8000


@cocotb.test()
async def busy_node_answers_ack_busy(dut):
    phy, host = await start(dut, phy_id=1)
    # A broadcast block write of 400 quadlets (to axis channels the board
    # does not have: no effect) keeps the request handler busy for 400
    # clocks; a read that arrives right behind it gets ack_busy_X and has
    # no effect; sent again, it is answered.
    phy.receive(pk.write_block(0xFFFF, HOST, 0x0080, bytes(1600)))
    write = pk.write_quadlet(NODE, HOST, 3, 0x0777, tl=7)
    tx = await host.send(write)
    assert tx is not None and tx.packets == [bytes([pk.ack_byte(pk.ACK_BUSY_X)])]
    await host.clocks(500)
    assert await host.read(NODE, 3) == 0x1680
    ack, _ = await host.request(write)
    assert ack == pk.ACK_COMPLETE
    assert await host.read(NODE, 3) == 0x0777


@cocotb.test()
async def reboot_restores_power_up_state(dut):
    phy, host = await start(dut, phy_id=1)
    await host.write(NODE, 3, 0x0042)
    await host.write(NODE, 0x0011, 0x80001234)
    await host.write(NODE, 0, 0x000C0000)
    await host.send(pk.write_quadlet(pk.node_id(0), HOST, 0x1800, 0x00050008), wait=10)
    await host.clocks(400)
    assert await host.read(NODE, 0x1802) == 33 + 1          # own entry + timing
    await host.write(NODE, 0, 0x00300000)                     # reboot
    await host.clocks(600)                                     # hub memory cleared
    assert await host.read(NODE, 3) == 0x1680
    assert await host.read(NODE, 0x0011) == 0x8000
    assert (await host.read(NODE, 0)) & (1 << 18) == 0
    assert await host.read(NODE, 0x1802) == 0 and await host.read(NODE, 0x1800) == 0
    assert await host.read_block(NODE, 0x1000, 8) == [0] * 8


@cocotb.test()
async def query_by_block_write_and_hub_registers(dut):
    phy, host = await start(dut, phy_id=1)
    # A block write to 0x1800 takes the query from its first quadlet.
    ack, _ = await host.request(pk.write_block(NODE, HOST, 0x1800, pk.to_bytes([0x00090008, 0])))
    assert ack == pk.ACK_COMPLETE
    await host.clocks(400)
    assert await host.read(NODE, 0x1800) == 0x00090008
    assert await host.read(NODE, 0x1802) == 34
    # Sequence 0 is not a query: ignored.
    await host.write(NODE, 0x1800, 0x00000008)
    assert await host.read(NODE, 0x1800) == 0x00090008
    # A status broadcast whose size field does not match its length is not stored.
    bad = [0x00090020] + [0] * 32
    await host.send(pk.write_block(0xFFFF, pk.node_id(2), 0xFFFFFF001000, pk.to_bytes(bad), pri=0xA))
    assert await host.read(NODE, 0x1802) == 34
