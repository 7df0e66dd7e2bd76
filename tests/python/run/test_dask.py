"""Tiles as tasks on a Dask distributed cluster (python/m3c2kit/run/, docs/scaling.md): the
result equals the single in-memory run, also when a worker dies in the middle of a task."""
from __future__ import annotations

import filecmp
import functools
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")
cloudpickle = pytest.importorskip("cloudpickle")

from m3c2kit import api  # noqa: E402
from m3c2kit.io import read_cloud  # noqa: E402
from m3c2kit.run.tasks import compute_tile
from m3c2kit.run.tiled import TiledOptions, run_tiled  # noqa: E402
from m3c2kit.output.writing import write  # noqa: E402

REPO = Path(__file__).resolve().parents[3]
REF, CMP = REPO / "data" / "toronto-ttp" / "TTP_15.laz", REPO / "data" / "toronto-ttp" / "TTP_23.laz"
PARAMS = dict(normal_scale="3,6", projection_scale=4, max_depth=6, core_spacing=4)
FIELDS = ("core", "distance", "lod", "significant", "n1", "n2", "sigma1", "sigma2", "i1", "i2", "normal",
          "normal_scale", "roughness", "status")

# The crashing task below is defined in this test module, which the workers cannot import:
# ship it by value.
cloudpickle.register_pickle_by_value(sys.modules[__name__])


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None,
                                  silence_logs=50) as c, distributed.Client(c) as client:
        yield c, client


@pytest.fixture(scope="module")
def untiled(tmp_path_factory):
    ref, cmp_ = read_cloud(REF), read_cloud(CMP)
    full = api.compare(ref, cmp_, **PARAMS)
    path = tmp_path_factory.mktemp("untiled") / "untiled.csv"
    write(path, full, like=ref)  # the core points' attributes too: tiled runs carry them (m3c2kit.run.attributes)
    return full, path


def assert_same(full, tiled):
    for name in FIELDS:
        a, b = np.asarray(getattr(full, name)), np.asarray(getattr(tiled, name))
        assert a.shape == b.shape and a.dtype == b.dtype, name
        assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), name


@pytest.mark.slow
def test_local_cluster_equals_single_run(cluster, untiled, tmp_path):
    _, client = cluster
    full, expected = untiled
    out = tmp_path / "dask.csv"
    rep = run_tiled(REF, CMP, tiling=TiledOptions(client=client, tile_size=90), output=out, return_result=True,
                    **PARAMS)
    assert rep.dask and rep.workers == 2 and rep.tiles > 10
    assert_same(full, rep.result)
    assert filecmp.cmp(out, expected, shallow=False)


@pytest.mark.slow
def test_cli_dask_scheduler(cluster, untiled, tmp_path):
    # As a user runs it: its own process, its own client of the running scheduler.
    c, _ = cluster
    out = tmp_path / "cli.csv"
    proc = subprocess.run([sys.executable, "-m", "m3c2kit", "compare", str(REF), str(CMP), "-o", str(out),
                           "--normal-scale", "3,6", "--projection-scale", "4", "--max-depth", "6", "--core-spacing",
                           "4", "--tile-size", "120", "--dask-scheduler", c.scheduler_address, "--quiet"],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert filecmp.cmp(out, untiled[1], shallow=False)


def die_once(task, params, threads, marker_dir):
    """Kills its worker process the first time it runs tile 3: the tile must be recomputed on
    another worker, with no row lost or duplicated."""
    marker = Path(marker_dir) / f"tile-{task.tile}"
    if task.tile == 3 and not marker.exists():
        marker.touch()
        os._exit(13)
    return compute_tile(task, params, threads)


def raise_once(task, params, threads, marker_dir):
    marker = Path(marker_dir) / f"raised-{task.tile}"
    if task.tile % 4 == 1 and not marker.exists():
        marker.touch()
        raise OSError("transient failure")
    return compute_tile(task, params, threads)


@pytest.mark.slow
@pytest.mark.parametrize("task_fn", [die_once, raise_once], ids=["worker-dies", "task-raises"])
def test_failed_tiles_are_retried(cluster, untiled, tmp_path, task_fn):
    _, client = cluster
    full, expected = untiled
    markers = tmp_path / "markers"
    markers.mkdir()
    out = tmp_path / "retried.csv"
    tiling = TiledOptions(client=client, tile_size=90, retries=2,
                          task_fn=functools.partial(task_fn, marker_dir=str(markers)))
    rep = run_tiled(REF, CMP, tiling=tiling, output=out, return_result=True, **PARAMS)
    assert any(markers.iterdir()), "the failure was not triggered"
    assert rep.core_points == len(full)
    assert_same(full, rep.result)
    assert filecmp.cmp(out, expected, shallow=False)
