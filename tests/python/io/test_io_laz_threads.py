"""LAZ decoding and encoding on the run's threads (m3c2kit.io.laz_threads): the parallel lazrs
coder writes the very bytes and reads the very points the serial one does, and no more threads
than asked are used."""
from __future__ import annotations

import laspy
import numpy as np
import pytest

import m3c2kit
from m3c2kit.io import laz_threads


@pytest.fixture
def fresh(monkeypatch):
    """laz_threads as in a new process with no RAYON_NUM_THREADS; restored afterwards."""
    monkeypatch.delenv("RAYON_NUM_THREADS", raising=False)
    monkeypatch.setattr(laz_threads, "_pool", None)
    monkeypatch.setattr(laz_threads, "_requested", 0)
    return laz_threads


def test_backend_follows_the_thread_limit(fresh):
    import os

    fresh.set_threads(1)
    assert fresh.backend() == laspy.LazBackend.Lazrs
    assert "RAYON_NUM_THREADS" not in os.environ  # one thread: the pool is not even started
    fresh.set_threads(3)
    assert fresh.backend() == laspy.LazBackend.LazrsParallel
    assert os.environ["RAYON_NUM_THREADS"] == "3"
    fresh.set_threads(2)  # the pool holds 3 threads: fewer asked means serial, never more threads
    assert fresh.backend() == laspy.LazBackend.Lazrs
    fresh.set_threads(4)
    assert fresh.backend() == laspy.LazBackend.LazrsParallel


def test_a_user_pool_size_is_kept(fresh, monkeypatch):
    import os

    monkeypatch.setenv("RAYON_NUM_THREADS", "2")
    fresh.set_threads(8)
    assert fresh.backend() == laspy.LazBackend.LazrsParallel
    assert os.environ["RAYON_NUM_THREADS"] == "2"
    fresh.set_threads(1)
    assert fresh.backend() == laspy.LazBackend.Lazrs
    with pytest.raises(ValueError):
        fresh.set_threads(-1)


def _cloud(n=130_000):  # more than two 50,000-point LAZ chunks: the parallel coder has work to split
    rng = np.random.default_rng(19)
    xyz = np.round(rng.uniform(0, 100, (n, 3)), 3)
    fields = {"intensity": rng.integers(0, 65535, n).astype(np.uint16),
              "distance": rng.normal(0, 1, n).astype(np.float32),
              "status": rng.integers(0, 5, n).astype(np.uint8)}
    return xyz, fields


def test_parallel_and_serial_write_the_same_bytes_and_read_the_same_points(fresh, tmp_path, monkeypatch):
    used = []
    pick = fresh.backend
    monkeypatch.setattr(fresh, "backend", lambda: used.append(pick()) or used[-1])
    xyz, fields = _cloud()
    paths = {}
    for threads in (1, 2):
        fresh.set_threads(threads)
        paths[threads] = tmp_path / f"t{threads}.laz"
        m3c2kit.io.write_cloud_table(paths[threads], xyz, fields)
    assert used == [laspy.LazBackend.Lazrs, laspy.LazBackend.LazrsParallel]  # both coders ran
    assert paths[1].read_bytes() == paths[2].read_bytes()

    clouds = {}
    for threads in (1, 2):
        fresh.set_threads(threads)
        clouds[threads] = m3c2kit.read(paths[1])
    assert used[2:] == [laspy.LazBackend.Lazrs, laspy.LazBackend.LazrsParallel]
    np.testing.assert_array_equal(clouds[1].xyz, clouds[2].xyz)
    np.testing.assert_allclose(clouds[1].xyz, xyz, rtol=0, atol=1e-6)  # LAS stores scaled integers
    assert clouds[1].fields.keys() == clouds[2].fields.keys()
    for name in clouds[1].fields:
        np.testing.assert_array_equal(clouds[1].fields[name], clouds[2].fields[name], err_msg=name)
