"""Cross-check: the HDL node against the software board (firelink-board).

The stream comes from `cargo run -p firelink-board --example hdl_stream`
(path in FIRELINK_HDL_STREAM, default hdl/build/stream.json): every packet
board 1 received in a recorded session on the simulated bus, at the clock
its last bit arrived, with the sensor values of the board's plant at that
moment, and the software board's replies and status broadcasts.

Here the same packets reach the HDL node (BOARD_ID 1) through the PHY model
at the same clocks (the node's `now` counts the same 49.152 MHz clocks from
power-up), with the same values on its QLA inputs and the motor-supply
comparator switching when the plant's did. The bus grants the node's status
broadcast so that it ends when the software board's did. Then:
- every ack and every response packet must be byte-identical;
- a packet the software board ignored must get nothing from the node;
- every status broadcast must be byte-identical, and its bus request must
  leave at the software board's ready clock plus the node's fixed request
  pipeline (REQUEST_DELAY + 3 clocks), to the clock.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import cocotb
from cocotb.clock import Clock
from cocotb.triggers import FallingEdge, RisingEdge, Timer

from harness import CLOCK_PS, set_inputs
from phy_model import REQ_IMM, REQ_ISO, CTL_IDLE, Phy, phy_of

STREAM = Path(os.environ.get("FIRELINK_HDL_STREAM",
                             Path(__file__).resolve().parent.parent / "build" / "stream.json"))

# Clocks from the PHY driving the first idle after a packet to the node's
# packet clock (pins registered, rx_end registered, descriptor registered).
RX_LATENCY = 2
# Clocks from the slot instant to the LREQ start bit: REQUEST_DELAY (16)
# + status_broadcast, link_ctrl and phy_lreq_tx registers.
REQUEST_PIPELINE = 16 + 3
# Clocks from the PHY driving the grant to the link releasing the lines,
# beyond the packet's bytes; the node stores its own broadcast one clock
# after that.
GRANT_TO_END = 6
STORE_AFTER_END = 2


@cocotb.test()
async def replay_matches_software_board(dut):
    stream = json.loads(STREAM.read_text())
    set_inputs(dut, **stream["initial"], supply_good=0)
    dut.phy_ctl_i.value = 0
    dut.phy_d_i.value = 0
    cocotb.start_soon(Clock(dut.clk, CLOCK_PS, unit="ps", impl="gpi").start())
    dut.rst.value = 1
    for _ in range(3):
        await RisingEdge(dut.clk)
    await FallingEdge(dut.clk)
    dut.rst.value = 0      # the next rising edge starts clock 0
    phy = phy_of(dut, regs=bytearray(stream["phy_registers"]))
    phy.clock_ps = CLOCK_PS

    expected_rx = []        # (event, index of the transmission that answers it)
    transmissions = []      # (kind, Transmission, rx index or broadcast index)
    state = {"last_rx": None, "broadcast": 0}
    grant_at = []           # per broadcast: when the PHY should grant it

    broadcasts = stream["broadcasts"]
    tx_done = [e["clock"] for e in stream["events"] if e["kind"] == "tx_done"]
    assert len(tx_done) == len(broadcasts), "every broadcast went out once"
    for end, bc in zip(tx_done, broadcasts):
        length = len(bytes.fromhex(bc["bytes"]))
        grant_at.append(end - STORE_AFTER_END - GRANT_TO_END - length)

    def on_transmission(_phy, tx):
        if tx.request is not None and tx.request.kind == REQ_ISO:
            transmissions.append(("broadcast", tx, state["broadcast"]))
            state["broadcast"] += 1
        else:
            transmissions.append(("reply", tx, state["last_rx"]))

    def grant_policy(p, now):
        req = p.bus_request
        if req.kind == REQ_IMM:
            return True
        k = state["broadcast"]
        return k < len(grant_at) and now >= grant_at[k] and p.idle_clocks >= 1

    phy.on_transmission = on_transmission
    phy.grant_policy = grant_policy

    # The timeline: every event at the clock it belongs to.
    def rx_action(index, event):
        cycles = Phy.receive_cycles(bytes.fromhex(event["bytes"]), event["speed"])

        def act(p, now):
            set_inputs(dut, **event["inputs"], supply_good=int(dut.supply_good.value))
            p.drive.extend(cycles)
            p.drive.append((CTL_IDLE, 0))
            state["last_rx"] = index
        return event["clock"] - RX_LATENCY - len(cycles), act

    actions = []
    for event in stream["events"]:
        kind = event["kind"]
        if kind == "rx":
            index = len(expected_rx)
            expected_rx.append(event)
            actions.append(rx_action(index, event))
        elif kind == "reset":
            actions.append((event["clock"], lambda p, now, e=event: p.bus_reset(e["phy_id"])))
        elif kind == "supply_good":
            def good(p, now):
                dut.supply_good.value = 1
            actions.append((event["clock"], good))
    actions.sort(key=lambda a: a[0])
    phy.timeline.extend(actions)
    cocotb.start_soon(phy.run())

    # Run to the end of the stream.
    last = max(a[0] for a in actions) + 3000
    while int(dut.now.value) < last:
        ahead = last - int(dut.now.value)
        await Timer(min(ahead, 200_000) * CLOCK_PS, "ps")
    for _ in range(50):
        await FallingEdge(dut.clk)

    assert not phy.errors, phy.errors[:5]

    # Replies: packet by packet.
    replies = {i: tx for kind, tx, i in transmissions if kind == "reply"}
    compared = 0
    silent = 0
    for i, event in enumerate(expected_rx):
        want = event["reply"]
        got = replies.get(i)
        if want is None:
            assert got is None or got.packets == [], \
                f"packet {i} at clock {event['clock']}: the software board ignored it, the node sent {got.packets}"
            silent += 1
            continue
        assert got is not None and got.packets, \
            f"packet {i} at clock {event['clock']} ({event['bytes'][:24]}...): no reply from the node"
        ack = got.packets[0]
        assert ack == bytes([(want["ack"] << 4) | (~want["ack"] & 0xF)]), \
            f"packet {i} at clock {event['clock']}: ack {ack.hex()} vs {want['ack']:#x}"
        if want["response"] is None:
            assert len(got.packets) == 1, f"packet {i}: unexpected response"
        else:
            assert len(got.packets) == 2, f"packet {i}: no response"
            want_bytes = bytes.fromhex(want["response"])
            if got.packets[1] != want_bytes:
                diff = [k for k in range(0, max(len(want_bytes), len(got.packets[1])), 4)
                        if got.packets[1][k:k + 4] != want_bytes[k:k + 4]]
                raise AssertionError(
                    f"packet {i} at clock {event['clock']}: response differs at byte offsets {diff[:8]}\n"
                    f"  node    {got.packets[1].hex()}\n  software {want_bytes.hex()}")
        compared += 1

    # Status broadcasts: one bus request each, bytes, the request's clock.
    iso = [r for r in phy.requests if r.kind == REQ_ISO]
    assert len(iso) == len(broadcasts), f"{len(iso)} broadcast requests for {len(broadcasts)} broadcasts"
    sent = [tx for kind, tx, _ in transmissions if kind == "broadcast"]
    assert len(sent) == len(broadcasts), f"{len(sent)} broadcasts vs {len(broadcasts)}"
    offsets = []
    for k, (tx, bc) in enumerate(zip(sent, broadcasts)):
        assert tx.packets == [bytes.fromhex(bc["bytes"])], \
            f"broadcast {k}: node {tx.packets[0].hex() if tx.packets else None}\n  software {bc['bytes']}"
        offsets.append(tx.request.start - bc["ready_clock"])
    assert offsets and all(o == REQUEST_PIPELINE for o in offsets), \
        f"request clocks minus the software board's ready clocks: {sorted(set(offsets))}"

    dut._log.info(
        "cross-check: %d packets replayed, %d replies compared byte for byte (%d silent), "
        "%d status broadcasts identical, every bus request at ready + %d clocks",
        len(expected_rx), compared, silent, len(sent), REQUEST_PIPELINE)
    Path(os.environ.get("FIRELINK_HDL_REPORT", STREAM.with_suffix(".report"))).write_text(
        f"packets {len(expected_rx)}\nreplies_compared {compared}\nsilent {silent}\n"
        f"broadcasts {len(sent)}\nrequest_offset {REQUEST_PIPELINE}\n")
