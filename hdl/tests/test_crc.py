"""crc32_1394 against shared/vectors/crc1394.json, at every step width
(2, 4 and 8 bits per clock, as the PHY delivers S100, S200 and S400), and
against the bit-serial reference on random data."""

from __future__ import annotations

import json
import random
from pathlib import Path

import cocotb
from cocotb.triggers import Timer

from packets import crc1394

VECTORS = Path(__file__).resolve().parents[3] / "shared" / "vectors" / "crc1394.json"
if not VECTORS.exists():
    VECTORS = Path("/work/shared/vectors/crc1394.json")
WIDTH_BITS = {0: 2, 1: 4, 2: 8}


async def run_crc(dut, data: bytes, width: int) -> int:
    """Feed `data` in steps of 2/4/8 bits; return the complemented register."""
    crc = 0xFFFFFFFF
    bits = WIDTH_BITS[width]
    for byte in data:
        for shift in range(8 - bits, -1, -bits):
            chunk = (byte >> shift) & ((1 << bits) - 1)
            dut.crc_in.value = crc
            dut.data.value = (chunk << (8 - bits)) & 0xFF
            dut.width.value = width
            await Timer(1, "ns")
            crc = int(dut.crc_out.value)
    return crc ^ 0xFFFFFFFF


@cocotb.test()
async def shared_vectors_at_every_width(dut):
    vectors = json.loads(VECTORS.read_text())
    check = vectors["check"]
    for width in (0, 1, 2):
        got = await run_crc(dut, check["ascii"].encode(), width)
        assert got == int(check["crc"], 16), f"width {width}: {got:08x}"
        for v in vectors["vectors"]:
            data = b"".join(int(q, 16).to_bytes(4, "big") for q in v["quadlets"])
            got = await run_crc(dut, data, width)
            assert got == int(v["crc"], 16), f"{v['what']} at width {width}: {got:08x}"


@cocotb.test()
async def random_data_matches_bit_serial_reference(dut):
    rng = random.Random(1394)
    for _ in range(20):
        data = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 40)))
        width = rng.randrange(3)
        assert await run_crc(dut, data, width) == crc1394(data)
