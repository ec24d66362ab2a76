"""A behavioural IEEE 1394a PHY for cocotb testbenches: it drives the
link's CTL[1:0]/D[7:0] inputs as a PHY does and watches the link's outputs.

What it does (shared/spec/ieee1394.md, "Link-PHY interface"):
- receive: CTL = receive with data-on (D = 0xFF), the speed code (S100 00xxxxxx,
  S200 0100xxxx, S400 01010000), then the packet at 2/4/8 bits per clock on
  D[7:6]/D[7:4]/D[7:0], then CTL = idle;
- status transfers: 2 bits per clock on D[7:6] (S[0] first), 4 bits or 16
  bits (status, register address, register data);
- LREQ: decodes the serial requests (bus requests with type and speed,
  register reads and writes, acceleration control);
- grants: CTL = grant for one clock; then records what the link sends
  (CTL = transmit bytes, hold between concatenated packets, idle at the end);
- bus reset: the bus-reset status, self-ID packets, then the register 0
  status carrying the new physical ID;
- PHY registers as the simulated bus keeps them (regs 1, 4, 5, 7 writable).

All sampling and driving happens on the falling clock edge, so values are
stable around the rising edge the design uses. `now` is the design's own
clock counter (the node's `now` output), read at each falling edge.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import cocotb
from cocotb.triggers import Event, FallingEdge, First, Timer

CTL_IDLE, CTL_RECEIVE, CTL_STATUS, CTL_GRANT = 0, 1, 2, 3
LINK_IDLE, LINK_TRANSMIT, LINK_HOLD = 0, 1, 2

REQ_IMM, REQ_ISO, REQ_PRI, REQ_FAIR, REQ_RDREG, REQ_WRREG, REQ_ACCEL = range(7)
REQ_NAMES = ["imm", "iso", "priority", "fair", "rdreg", "wrreg", "accel"]
SPEED_CODES = {0: 0x00, 1: 0x40, 2: 0x50}        # on D during the speed cycle
WIDTH = {0: 2, 1: 4, 2: 8}                        # bits per clock
S100, S200, S400 = 0, 1, 2

STATUS_BUS_RESET = 1 << 13


@dataclass
class LinkRequest:
    """One LREQ frame as decoded."""

    start: int          # `now` at the start bit
    kind: int           # REQ_*
    speed: int = 0      # bus requests: 3-bit speed code
    addr: int = 0
    data: int = 0

    @property
    def name(self) -> str:
        return REQ_NAMES[self.kind] if self.kind < len(REQ_NAMES) else f"type{self.kind}"


@dataclass
class Transmission:
    """What the link sent in one bus ownership."""

    granted: int                  # `now` when the grant was driven
    packets: list = field(default_factory=list)   # bytes of each packet
    first_data: int | None = None  # `now` at the first byte
    end: int | None = None         # `now` when the link released the lines
    request: LinkRequest | None = None


def board_phy_registers(phy_id: int, ports: int = 2) -> bytearray:
    """The PHY registers a board's node has on the simulated bus."""
    regs = bytearray(16)
    regs[0] = (phy_id & 0x3F) << 2
    regs[1] = 63
    regs[2] = (7 << 5) | (ports & 0x1F)
    regs[3] = (2 << 5) | 0x0F
    regs[4] = 0x84
    return regs


class Phy:
    """The PHY of one node. `grant_policy` decides when a bus request is
    granted (default: as soon as the lines are idle); `on_transmission` is
    called with each finished Transmission."""

    clock_ps = 20346

    def __init__(self, clk, ctl_i, d_i, ctl_o, d_o, oe, lreq, now, regs=None, name="phy"):
        self.clk, self.ctl_i, self.d_i = clk, ctl_i, d_i
        self.ctl_o, self.d_o, self.oe, self.lreq, self.now_sig = ctl_o, d_o, oe, lreq, now
        self.name = name
        self.regs = regs if regs is not None else board_phy_registers(0)
        self.drive: deque = deque()      # (ctl, d) per clock
        self.requests: list[LinkRequest] = []
        self.bus_request: LinkRequest | None = None
        self.transmissions: list[Transmission] = []
        self.on_transmission = None
        self.on_request = None
        self.grant_policy = None         # callable(phy, now) -> bool
        self.idle_clocks = 0
        self.now = 0
        self._frame: list[int] | None = None
        self._frame_start = 0
        self._tx: Transmission | None = None
        self._tx_seen = False
        self._cur: bytearray | None = None
        self._granting = False
        self._pending_status: deque = deque()
        self.errors: list[str] = []
        self._wake = None
        # Actions at given clocks: (clock, callable(phy, now)), sorted.
        self.timeline: deque = deque()
        ctl_i.value = CTL_IDLE
        d_i.value = 0

    # ---- what the testbench asks for ------------------------------------------
    def receive(self, packet: bytes, speed: int = S400, data_on: int = 1) -> None:
        """Queue a packet for the link to receive (after what is queued)."""
        self.drive.extend(self.receive_cycles(packet, speed, data_on))
        self.drive.append((CTL_IDLE, 0))
        self.poke()

    @staticmethod
    def receive_cycles(packet: bytes, speed: int = S400, data_on: int = 1) -> list:
        cycles = [(CTL_RECEIVE, 0xFF)] * data_on + [(CTL_RECEIVE, SPEED_CODES[speed])]
        width = WIDTH[speed]
        for byte in packet:
            for shift in range(8 - width, -1, -width):
                chunk = (byte >> shift) & ((1 << width) - 1)
                cycles.append((CTL_RECEIVE, (chunk << (8 - width)) & 0xFF))
        return cycles

    def status(self, bits: int, full: bool) -> None:
        """Queue a status transfer (bits: S[0] in bit 15)."""
        n = 8 if full else 2
        for i in range(n):
            self.drive.append((CTL_STATUS, ((bits >> (14 - 2 * i)) & 3) << 6))
        self.drive.append((CTL_IDLE, 0))
        self.poke()

    def bus_reset(self, phy_id: int, self_ids: list | None = None) -> None:
        """A bus reset: the status, the self-ID packets, the new physical ID."""
        self.drive.clear()
        self.bus_request = None
        self.regs[0] = ((phy_id & 0x3F) << 2) | (self.regs[0] & 3)
        self.status(STATUS_BUS_RESET, full=False)
        for sid in self_ids if self_ids is not None else [self_id_packet(phy_id)]:
            self.receive(sid, S100)
        self.status((0 << 8) | self.regs[0], full=True)

    def grant(self) -> None:
        self._granting = True
        self.poke()

    # ---- the clock loop ------------------------------------------------------------
    def busy(self) -> bool:
        return bool(self.drive) or self._tx is not None or self._granting or \
            self._frame is not None or self.bus_request is not None or \
            bool(self._pending_status) or int(self.oe.value) == 1 or \
            (bool(self.timeline) and self.timeline[0][0] - self.now <= 4)

    async def run(self) -> None:
        while True:
            if not self.busy() and self._wake is None:
                # Nothing to do: sleep until the link raises LREQ, we are
                # woken, or the next timeline action is near.
                self._wake = Event()
                triggers = [self.lreq.value_change, self._wake.wait()]
                if self.timeline:
                    ahead = self.timeline[0][0] - self.now - 3
                    triggers.append(Timer(max(ahead, 1) * self.clock_ps, "ps"))
                await First(*triggers)
                self._wake = None
            await FallingEdge(self.clk)
            self.now = int(self.now_sig.value)
            self._sample()
            while self.timeline and self.timeline[0][0] <= self.now:
                _, action = self.timeline.popleft()
                action(self, self.now)
            self._drive_next()

    def poke(self) -> None:
        """Wake the loop after queueing work from outside."""
        if self._wake is not None:
            self._wake.set()

    def _sample(self) -> None:
        # LREQ frames.
        bit = int(self.lreq.value)
        if self._frame is None:
            if bit:
                self._frame = [1]
                self._frame_start = self.now
        else:
            self._frame.append(bit)
            f = self._frame
            if len(f) >= 4:
                kind = (f[1] << 2) | (f[2] << 1) | f[3]
                length = {REQ_RDREG: 9, REQ_WRREG: 17, REQ_ACCEL: 6}.get(kind, 8)
                if len(f) == length:
                    self._frame = None
                    self._request(kind, f)
        # The link driving the lines.
        oe = int(self.oe.value)
        if oe:
            ctl = int(self.ctl_o.value)
            if self._tx is None:
                self._tx = Transmission(granted=self.now, request=None)
                self.errors.append(f"link drove the lines without a grant at {self.now}")
            self._tx_seen = True
            if ctl == LINK_TRANSMIT:
                if self._cur is None:
                    self._cur = bytearray()
                    if self._tx.first_data is None:
                        self._tx.first_data = self.now
                self._cur.append(int(self.d_o.value))
            else:
                if self._cur is not None:
                    self._tx.packets.append(bytes(self._cur))
                    self._cur = None
        elif self._tx is not None and not self._granting and (
                self._tx_seen or self.now - self._tx.granted > 8):
            if self._cur is not None:
                self._tx.packets.append(bytes(self._cur))
                self._cur = None
            self._tx.end = self.now
            tx, self._tx = self._tx, None
            self._tx_seen = False
            self.transmissions.append(tx)
            self.idle_clocks = 0
            if self.on_transmission is not None:
                self.on_transmission(self, tx)

    def _request(self, kind: int, f: list[int]) -> None:
        def val(bits):
            v = 0
            for b in bits:
                v = (v << 1) | b
            return v
        req = LinkRequest(start=self._frame_start, kind=kind)
        if kind <= REQ_FAIR:
            req.speed = val(f[4:7])
            if f[7] != 0:
                self.errors.append(f"bus request without stop bit at {self.now}")
            self.bus_request = req
        elif kind == REQ_RDREG:
            req.addr = val(f[4:8])
            self._pending_status.append(req.addr)
        elif kind == REQ_WRREG:
            req.addr = val(f[4:8])
            req.data = val(f[8:16])
            if req.addr in (1, 4, 5, 7):
                self.regs[req.addr] = req.data
        self.requests.append(req)
        if self.on_request is not None:
            self.on_request(self, req)

    def _drive_next(self) -> None:
        if self._granting:
            self._granting = False
            self._tx = Transmission(granted=self.now, request=self.bus_request)
            self.bus_request = None
            self.ctl_i.value = CTL_GRANT
            self.d_i.value = 0
            self.idle_clocks = 0
            return
        if self.drive:
            if self._tx is not None or int(self.oe.value):
                self.errors.append(f"receive started while the link owns the bus at {self.now}")
            ctl, d = self.drive.popleft()
            self.ctl_i.value = ctl
            self.d_i.value = d
            self.idle_clocks = 0 if ctl != CTL_IDLE else self.idle_clocks + 1
            return
        self.ctl_i.value = CTL_IDLE
        self.d_i.value = 0
        if self._tx is not None or int(self.oe.value):
            self.idle_clocks = 0
            return
        self.idle_clocks += 1
        if self._pending_status:
            addr = self._pending_status.popleft()
            self.status((addr << 8) | self.regs[addr], full=True)
            return
        if self.bus_request is not None:
            policy = self.grant_policy or default_grant_policy
            if policy(self, self.now):
                self.grant()


def default_grant_policy(phy: Phy, now: int) -> bool:
    """Grant an immediate request at once, others after two idle clocks."""
    req = phy.bus_request
    if req is None:
        return False
    return req.kind == REQ_IMM or phy.idle_clocks >= 2


def self_id_packet(phy_id: int, link_active: bool = True, gap: int = 63, speed: int = 2) -> bytes:
    """A self-ID packet 0: the quadlet and its complement."""
    q = (0b10 << 30) | ((phy_id & 0x3F) << 24) | (int(link_active) << 22) | ((gap & 0x3F) << 16) \
        | ((speed & 3) << 14) | (1 << 11)
    return q.to_bytes(4, "big") + ((~q) & 0xFFFFFFFF).to_bytes(4, "big")


def phy_of(dut, regs=None, name="phy") -> Phy:
    """The PHY model on a firelink_node's pins."""
    return Phy(dut.clk, dut.phy_ctl_i, dut.phy_d_i, dut.phy_ctl_o, dut.phy_d_o, dut.phy_oe,
               dut.phy_lreq, dut.now, regs=regs, name=name)
