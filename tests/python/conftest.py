"""Shared pytest setup: makes the in-tree package importable and locates the shared test data."""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

# Prefer an installed m3c2 (e.g. `pip install .`); fall back to the source tree.
if importlib.util.find_spec("m3c2kit") is None:
    sys.path.insert(0, str(REPO / "python"))


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """`<repo>/../shared/data`, the read-only real-data folder; skips the test when absent."""
    path = REPO.parent / "shared" / "data"
    if not path.is_dir():
        pytest.skip(f"shared test data not found at {path}")
    return path


@pytest.fixture(scope="session")
def autzen_pair() -> Path:
    """The autzen-bmx pair with CloudCompare's and PDAL's outputs, copied into the repository
    (tests/data/pairs/autzen-bmx, PROVENANCE.md there): tests that need only it run from a clone."""
    return REPO / "tests" / "data" / "pairs" / "autzen-bmx"
