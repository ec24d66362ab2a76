"""Hostile arguments: every call raises one of the documented exceptions
(or Python's own TypeError/OverflowError for wrong types) and the
interpreter survives."""

import math
import random

import numpy as np
import pytest

import firelink

ALLOWED = (firelink.FirelinkError, TypeError, OverflowError, ValueError)

VALUES = [None, -1, 0, 1, 63, 64, 2**31, 2**64, -(2**63), math.nan, math.inf, -0.0, 1e300,
          "", "sim", "udp:", "udp:127.0.0.1:0", "\x00", "é", b"", b"\xff" * 9000, [], {}, object(),
          np.zeros(0), np.zeros(3), np.full(32, 1e9)]


def call(f, *args):
    try:
        f(*args)
    except ALLOWED:
        pass


def test_random_arguments_never_crash():
    rng = random.Random(7)
    io = firelink.IoSystem("sim:2")
    port = firelink.open("sim:1")
    targets = [
        firelink.open, firelink.decode_packet, firelink.parse_config, firelink.crc1394,
        port.read_quadlet, port.write_quadlet, port.read_block, port.write_block, port.wait,
        io.set_dac, io.set_current, io.set_power, io.set_watchdog, io.read_register,
        io.write_register, io.wait,
    ]
    for _ in range(600):
        f = rng.choice(targets)
        args = [rng.choice(VALUES) for _ in range(rng.randrange(4))]
        call(f, *args)
    # Still usable afterwards.
    assert io.read_all() in (True, False)
    assert len(port.scan()) == 1


def test_arrays_of_the_wrong_kind():
    io = firelink.IoSystem("sim:1")
    with pytest.raises(ALLOWED):
        io.set_dac(np.zeros((2, 2), dtype=np.int64))
    with pytest.raises(ALLOWED):
        io.set_current(np.zeros(4, dtype=np.float32))
    with pytest.raises(ALLOWED):
        io.set_dac(np.zeros(4, dtype=np.int64)[::2])
