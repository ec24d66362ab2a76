"""Packets: decode, encode, CRC; bad bytes raise PacketError, never crash."""

import random

import pytest

import firelink

READ_QUADLET = bytes.fromhex("ffc11540ffc2000000000007b2b02823")


def test_decode_then_encode_is_identity():
    fields = firelink.decode_packet(READ_QUADLET)
    assert fields["tcode_name"] == "read_request_quadlet"
    assert fields["destination_id"] == 0xFFC1
    # Header quadlets: ffc1 1540 | ffc2 0000 | 0000 0007: the source is
    # node 2 of the local bus, the offset's high 16 bits are 0, its low 32
    # bits 7 (quadlet register 7, FW_VERSION).
    assert fields["source_id"] == 0xFFC2
    assert fields["offset"] == 7
    assert (fields["tl"], fields["rt"], fields["pri"]) == (5, 1, 0)
    assert fields["header_crc_ok"] is True
    assert firelink.encode_packet(fields) == READ_QUADLET


def test_encode_from_keywords():
    raw = firelink.encode_packet(tcode_name="write_request_quadlet", destination_id=0xFFC0, offset=3, quadlet_data=0x1234)
    back = firelink.decode_packet(raw)
    assert back["quadlet_data"] == 0x1234 and back["offset"] == 3


def test_bridge_datagrams_carry_the_control_word():
    raw = firelink.encode_packet(firelink.decode_packet(READ_QUADLET), bridge=True, generation=5)
    assert firelink.decode_packet(raw, bridge=True)["generation"] == 5


def test_the_crc_matches_the_header():
    assert firelink.crc1394(READ_QUADLET[:12]) == int.from_bytes(READ_QUADLET[12:], "big")


def test_missing_and_out_of_range_fields_are_named():
    with pytest.raises(firelink.PacketError, match="missing field quadlet_data"):
        firelink.encode_packet(tcode_name="write_request_quadlet", destination_id=0xFFC0, offset=0)
    with pytest.raises(firelink.PacketError, match="tl"):
        firelink.encode_packet(tcode_name="read_request_quadlet", destination_id=0xFFC0, offset=0, tl=99)
    with pytest.raises(firelink.PacketError):
        firelink.encode_packet(tcode_name="no_such_tcode", destination_id=0)
    with pytest.raises(firelink.PacketError):
        firelink.encode_packet(tcode_name="read_request_quadlet", destination_id=object())


def test_random_bytes_never_crash():
    rng = random.Random(1)
    for _ in range(3000):
        data = bytes(rng.randrange(256) for _ in range(rng.randrange(40)))
        try:
            firelink.decode_packet(data, bridge=rng.random() < 0.5)
        except firelink.PacketError:
            pass


def test_decode_takes_bytes():
    with pytest.raises(firelink.PacketError):
        firelink.decode_packet("ffc1")  # type: ignore[arg-type]
