"""Shared pytest setup: makes the in-tree package importable and locates the shared test data."""
from __future__ import annotations

import importlib.util
import signal
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

# Prefer an installed m3c2 (e.g. `pip install .`); fall back to the source tree.
if importlib.util.find_spec("m3c2kit") is None:
    sys.path.insert(0, str(REPO / "python"))


# A shell starts a background job (`.ci/run &`, a CI runner's job) with SIGINT ignored, and an
# ignored signal stays ignored in every child: the tests that interrupt `m3c2` runs would then
# test nothing. A handled signal is reset to the default in a child, whose Python then makes
# SIGINT a KeyboardInterrupt as a terminal's Ctrl-C does.
signal.signal(signal.SIGINT, signal.default_int_handler)


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
