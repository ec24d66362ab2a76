"""IEEE 1394 asynchronous packets for the testbenches: the CRC, builders for
the requests a host sends and decoders for what a node answers.

Facts: shared/spec/ieee1394.md (header layout, tcodes, acks, CRC). This is
the testbench's own reference, written independently of the Verilog: the
CRC here is the plain bit-serial definition.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

POLY = 0x04C11DB7

TC_WRITE_QUADLET = 0x0
TC_WRITE_BLOCK = 0x1
TC_WRITE_RESPONSE = 0x2
TC_READ_QUADLET = 0x4
TC_READ_BLOCK = 0x5
TC_READ_QUADLET_RESPONSE = 0x6
TC_READ_BLOCK_RESPONSE = 0x7
TC_LOCK = 0x9

ACK_COMPLETE = 0x1
ACK_PENDING = 0x2
ACK_BUSY_X = 0x4
ACK_DATA_ERROR = 0xD
ACK_TYPE_ERROR = 0xE

RCODE_COMPLETE = 0
RCODE_TYPE_ERROR = 6
RCODE_ADDRESS_ERROR = 7

LOCAL_BUS = 0xFFC0


def crc1394(data: bytes) -> int:
    """CRC-32/BZIP2 over the bytes, most significant bit first."""
    crc = 0xFFFFFFFF
    for byte in data:
        for bit in range(7, -1, -1):
            fb = ((crc >> 31) & 1) ^ ((byte >> bit) & 1)
            crc = (crc << 1) & 0xFFFFFFFF
            if fb:
                crc ^= POLY
    return crc ^ 0xFFFFFFFF


def quadlets(data: bytes) -> list[int]:
    return [int.from_bytes(data[i:i + 4], "big") for i in range(0, len(data) - len(data) % 4, 4)]


def to_bytes(words: list[int]) -> bytes:
    return b"".join(struct.pack(">I", w & 0xFFFFFFFF) for w in words)


def ack_byte(code: int) -> int:
    return ((code & 0xF) << 4) | (~code & 0xF)


def _q0(dest: int, tl: int, tcode: int, pri: int = 0, rt: int = 0) -> int:
    return ((dest & 0xFFFF) << 16) | ((tl & 0x3F) << 10) | ((rt & 3) << 8) | ((tcode & 0xF) << 4) | (pri & 0xF)


def _with_crc(header: list[int], data: bytes = b"") -> bytes:
    h = to_bytes(header)
    out = h + struct.pack(">I", crc1394(h))
    if data:
        padded = data + bytes(-len(data) % 4)
        out += padded + struct.pack(">I", crc1394(padded))
    return out


def node_id(phy: int) -> int:
    return LOCAL_BUS | (phy & 0x3F)


def write_quadlet(dest: int, src: int, offset: int, value: int, tl: int = 0) -> bytes:
    return _with_crc([_q0(dest, tl, TC_WRITE_QUADLET), (src << 16) | ((offset >> 32) & 0xFFFF),
                      offset & 0xFFFFFFFF, value & 0xFFFFFFFF])


def write_block(dest: int, src: int, offset: int, data: bytes, tl: int = 0, pri: int = 0) -> bytes:
    return _with_crc([_q0(dest, tl, TC_WRITE_BLOCK, pri), (src << 16) | ((offset >> 32) & 0xFFFF),
                      offset & 0xFFFFFFFF, (len(data) & 0xFFFF) << 16], data)


def read_quadlet(dest: int, src: int, offset: int, tl: int = 0) -> bytes:
    return _with_crc([_q0(dest, tl, TC_READ_QUADLET), (src << 16) | ((offset >> 32) & 0xFFFF),
                      offset & 0xFFFFFFFF])


def read_block(dest: int, src: int, offset: int, length: int, tl: int = 0) -> bytes:
    return _with_crc([_q0(dest, tl, TC_READ_BLOCK), (src << 16) | ((offset >> 32) & 0xFFFF),
                      offset & 0xFFFFFFFF, (length & 0xFFFF) << 16])


def lock_request(dest: int, src: int, offset: int, data: bytes, tl: int = 0) -> bytes:
    return _with_crc([_q0(dest, tl, TC_LOCK), (src << 16) | ((offset >> 32) & 0xFFFF),
                      offset & 0xFFFFFFFF, ((len(data) & 0xFFFF) << 16) | 2], data)


@dataclass
class Packet:
    """A decoded asynchronous packet (header fields, data, CRC verdicts)."""

    raw: bytes
    dest: int
    tl: int
    rt: int
    tcode: int
    pri: int
    source: int
    rcode: int
    offset: int
    q3: int
    data: bytes
    header_crc_ok: bool
    data_crc_ok: bool | None

    @property
    def data_length(self) -> int:
        return self.q3 >> 16

    @property
    def words(self) -> list[int]:
        return quadlets(self.data)


HEADER_QUADLETS = {0x0: 4, 0x1: 4, 0x2: 3, 0x4: 3, 0x5: 4, 0x6: 4, 0x7: 4, 0x9: 4, 0xB: 4}
BLOCK_TCODES = {0x1, 0x7, 0x9, 0xB}


def decode(raw: bytes) -> Packet:
    """Decode a packet; raises ValueError when it is too short."""
    if len(raw) < 4:
        raise ValueError(f"packet of {len(raw)} bytes")
    q = quadlets(raw)
    tcode = (q[0] >> 4) & 0xF
    hq = HEADER_QUADLETS.get(tcode)
    if hq is None or len(q) < hq + 1:
        raise ValueError(f"tcode {tcode:#x} packet of {len(raw)} bytes")
    header = raw[:4 * hq]
    hcrc_ok = crc1394(header) == q[hq]
    q3 = q[3] if hq == 4 else 0
    data = b""
    dcrc_ok = None
    if tcode in BLOCK_TCODES and (q3 >> 16) > 0:
        n = q3 >> 16
        padded = (n + 3) // 4 * 4
        start = 4 * (hq + 1)
        data = raw[start:start + n]
        crc_word = raw[start + padded:start + padded + 4]
        dcrc_ok = len(crc_word) == 4 and crc1394(raw[start:start + padded]) == int.from_bytes(crc_word, "big")
    return Packet(raw=raw, dest=q[0] >> 16, tl=(q[0] >> 10) & 0x3F, rt=(q[0] >> 8) & 3, tcode=tcode,
                  pri=q[0] & 0xF, source=q[1] >> 16, rcode=(q[1] >> 12) & 0xF,
                  offset=((q[1] & 0xFFFF) << 32) | q[2], q3=q3, data=data,
                  header_crc_ok=hcrc_ok, data_crc_ok=dcrc_ok)
