"""Shared fixtures: the repository's shipped configurations."""

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture
def configs_dir() -> Path:
    return REPO / "configs"


@pytest.fixture
def udp_timeout() -> float:
    """Seconds a port to the in-process emulator waits for an answer.

    Discovery reads 16 node IDs and waits this long for each one the
    emulated bus lacks (the port's default of 1 s made a one-board scan
    take 15 s); 0.25 s is still 2.5 times what the Rust UDP tests allow an
    unoptimised emulator on a loaded machine.
    """
    return 0.25
