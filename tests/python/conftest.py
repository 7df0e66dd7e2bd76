"""Shared pytest setup: makes the in-tree package importable and locates the shared test data."""
from __future__ import annotations

import importlib.util
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

# Prefer an installed m3c2 (e.g. `pip install .`); fall back to the source tree.
if importlib.util.find_spec("m3c2kit") is None:
    sys.path.insert(0, str(REPO / "python"))


def pytest_collection_finish(session):
    """A test module that puts another m3c2kit (python/ beside an installed one) first on
    sys.path makes every process started later (a Dask worker, a spawned child) import that one,
    which may lack _core: the cluster tests then fail far from the cause."""
    import m3c2kit
    tested = Path(m3c2kit.__file__).resolve().parent
    first = next((Path(p or ".").resolve() / "m3c2kit" for p in sys.path
                  if (Path(p or ".") / "m3c2kit" / "__init__.py").is_file()), None)
    if first is not None and first != tested:
        raise pytest.UsageError(f"a test module put {first.parent} first on sys.path; the tests use {tested}")


# A shell starts a background job (`.ci/run &`, a CI runner's job) with SIGINT ignored, and an
# ignored signal stays ignored in every child: the tests that interrupt `m3c2` runs would then
# test nothing. A handled signal is reset to the default in a child, whose Python then makes
# SIGINT a KeyboardInterrupt as a terminal's Ctrl-C does.
signal.signal(signal.SIGINT, signal.default_int_handler)
# m3c2 leaves a signal its caller ignores ignored (nohup: SIGHUP; cli/main.py): a suite started
# under nohup would then test nothing of SIGHUP, in this process or its children.
for _name in ("SIGHUP", "SIGQUIT", "SIGTERM"):
    if hasattr(signal, _name) and signal.getsignal(getattr(signal, _name)) == signal.SIG_IGN:
        signal.signal(getattr(signal, _name), signal.SIG_DFL)


@pytest.fixture
def pair(tmp_path) -> Path:
    """`tmp_path` holding ref.xyz, a 20 x 20 grid 0.1 apart, and cmp.xyz, the same 0.1 higher: the
    smallest pair every command takes, for the tests of options, inputs and messages (a test
    module that needs another pair defines its own `pair`)."""
    from synthetic import grid, write_xyz
    write_xyz(tmp_path / "ref.xyz", grid())
    write_xyz(tmp_path / "cmp.xyz", grid(z=0.1))
    return tmp_path


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


@pytest.fixture
def small_disk(tmp_path):
    """make(size) -> a folder on a real full-able disk: a tmpfs of `size` (e.g. "256k"), unmounted
    afterwards (root in a container that allows mount; the test is skipped with the reason elsewhere)."""
    mounted = []

    def make(size: str) -> Path:
        if os.geteuid() != 0 or shutil.which("mount") is None:
            pytest.skip("mounting a small tmpfs needs root and mount(8)")
        d = tmp_path / f"disk-{size}"
        d.mkdir()
        proc = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(d)],
                              capture_output=True, text=True)
        if proc.returncode != 0:
            pytest.skip(f"this container does not allow mounting a tmpfs ({proc.stderr.strip()})")
        mounted.append(d)
        return d

    yield make
    for d in mounted:
        subprocess.run(["umount", str(d)], capture_output=True)
