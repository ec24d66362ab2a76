"""Shared fixtures: the repository's shipped configurations."""

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture
def configs_dir() -> Path:
    return REPO / "configs"
