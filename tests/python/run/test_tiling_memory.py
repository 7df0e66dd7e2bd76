"""The memory plan of a tiled run (python/m3c2kit/run/memory.py, docs/scaling.md "Memory"): the fixed
costs (this process, the streaming and merge chunks) and the tiles share --memory-limit, chunks
sized from the plan leave the output bytes unchanged, and a small run's peak stays under its limit."""
from __future__ import annotations

import filecmp
import json
import subprocess
import sys
from pathlib import Path

import laspy
import numpy as np
import pytest

from child_env import child_env
from m3c2kit.run import memory as tiling
from m3c2kit.base.errors import UsageError
from m3c2kit.io.streaming import DEFAULT_CHUNK
from m3c2kit.run.memory import MemoryPlan, choose_tile_size, plan_memory
from m3c2kit.run.tiled import TiledOptions, run_tiled

MiB = 2**20
PARAMS = dict(normal_scale=1.0, projection_scale=0.5, max_depth=1.0)


@pytest.mark.parametrize("limit, resident", [(512 * MiB, 60 * MiB), (800_000_000, 110 * MiB), (3 * 2**30, 200 * MiB),
                                             (200 * MiB, 100 * MiB)])
def test_plan_keeps_every_phase_within_the_limit(limit, resident):
    plan = plan_memory(limit, resident)
    assert isinstance(plan, MemoryPlan)
    assert plan.base == max(tiling.BASE_BYTES, resident + tiling.HEADROOM_BYTES)
    budget = limit - plan.base
    for rows, per_row in ((plan.stream_rows, tiling.STREAM_BYTES_PER_ROW), (plan.merge_rows, tiling.MERGE_BYTES_PER_ROW)):
        assert tiling.MIN_CHUNK <= rows <= DEFAULT_CHUNK
        assert rows * per_row <= max(tiling.CHUNK_SHARE * budget, tiling.MIN_CHUNK * per_row)
    # The tile is sized from what the base leaves; the phases run one after the other.
    h, rho, rho_core = 0.51, 1e4, 2e3
    s = choose_tile_size(limit, h, rho, rho, rho_core, base=plan.base)
    tile = tiling.BYTES_PER_POINT * 2 * rho * (s + 2 * h) ** 2 + tiling.BYTES_PER_CORE * rho_core * s * s
    assert plan.base + max(plan.stream_bytes, plan.merge_bytes, tile) <= limit


def test_plan_chunks_shrink_with_the_limit_and_respect_chunk_size():
    small, big = plan_memory(300 * MiB, 60 * MiB), plan_memory(8 * 2**30, 60 * MiB)
    assert small.merge_rows < big.merge_rows == DEFAULT_CHUNK
    assert small.merge_rows < DEFAULT_CHUNK  # the merge chunk no longer costs a fixed 2^20 rows
    assert plan_memory(8 * 2**30, 60 * MiB, chunk_size=5000).merge_rows == 5000
    with pytest.raises(UsageError, match="too small"):
        plan_memory(100 * MiB, 80 * MiB)


def _las(path: Path, xyz: np.ndarray) -> None:
    header = laspy.LasHeader(version="1.4", point_format=6)
    header.scales, header.offsets = np.array([0.001] * 3), np.floor(xyz.min(axis=0))
    las = laspy.LasData(header)
    las.x, las.y, las.z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    las.write(path)


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    d = tmp_path_factory.mktemp("mem")
    rng = np.random.default_rng(11)
    n = 20_000
    xy = rng.uniform(0, 40, (n, 2))
    ref = np.column_stack([xy, 0.2 * np.sin(xy[:, 0] / 3) + rng.normal(0, 0.01, n)])
    cmp_ = ref + np.array([0.0, 0.0, 0.05]) + rng.normal(0, 0.01, ref.shape)
    _las(d / "ref.las", ref)
    _las(d / "cmp.las", cmp_)
    return d / "ref.las", d / "cmp.las"


def test_tile_larger_than_the_survey_is_one_tile(pair, tmp_path):
    ref, cmp_ = pair
    core = laspy.read(ref).xyz[::7]
    # The core points' first point is in the middle of the survey; the tiles start at its corner.
    core = np.concatenate([core[np.argsort(np.abs(core[:, 0] - 20) + np.abs(core[:, 1] - 20))[:1]], core])
    for c in (core, None):  # an in-memory core array; every reference point (anchored at the LAS header's minimum)
        rep = run_tiled(ref, cmp_, c, tiling=TiledOptions(tile_size=45.0), **PARAMS)
        assert rep.tiles == 1


def test_chunks_from_the_plan_keep_the_bytes(pair, tmp_path, monkeypatch):
    ref, cmp_ = pair
    out_plain, out_limited = tmp_path / "plain.laz", tmp_path / "limited.laz"
    run_tiled(ref, cmp_, output=out_plain, tiling=TiledOptions(tile_size=12.0), **PARAMS)
    # Tiny chunks: the plan must take its row counts from the (scaled) per-row costs.
    from m3c2kit.run import memory  # the executor's memory planning
    monkeypatch.setattr(memory, "MIN_CHUNK", 64)
    monkeypatch.setattr(memory, "MERGE_BYTES_PER_ROW", 2**20)
    monkeypatch.setattr(memory, "STREAM_BYTES_PER_ROW", 2**19)
    limit = tiling.rss_bytes() + tiling.HEADROOM_BYTES + 4000 * 2**20
    rep = run_tiled(ref, cmp_, output=out_limited, tiling=TiledOptions(tile_size=12.0, memory_limit=limit), **PARAMS)
    assert rep.memory_plan.merge_rows < 2000 and rep.memory_plan.stream_rows < 4000
    assert filecmp.cmp(out_plain, out_limited, shallow=False)


CHILD = r"""
import json, sys
from m3c2kit.run import memory
from m3c2kit.run.tiled import TiledOptions, run_tiled
def hwm():
    with open("/proc/self/status") as f:
        return next(int(l.split()[1]) * 1024 for l in f if l.startswith("VmHWM:"))
ref, cmp_, out, extra = sys.argv[1:5]
import laspy, numpy  # what a command-line run has loaded when it starts
limit = memory.rss_bytes() + memory.HEADROOM_BYTES + int(extra)
rep = run_tiled(ref, cmp_, output=out, tiling=TiledOptions(memory_limit=limit), normal_scale=1.0,
                projection_scale=0.5, max_depth=1.0, threads=2)
print(json.dumps(dict(limit=limit, peak=hwm(), tiles=rep.tiles)))
"""


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="needs /proc (Linux) for VmHWM")
def test_small_run_peak_stays_under_its_limit(tmp_path):
    rng = np.random.default_rng(5)
    n = 400_000
    xy = rng.uniform(0, 60, (n, 2))
    ref = np.column_stack([xy, 0.3 * np.sin(xy[:, 1] / 4) + rng.normal(0, 0.01, n)])
    cmp_ = ref + rng.normal(0, 0.01, ref.shape)
    _las(tmp_path / "ref.laz", ref)
    _las(tmp_path / "cmp.laz", cmp_)
    args = [str(tmp_path / "ref.laz"), str(tmp_path / "cmp.laz"), str(tmp_path / "out.laz"), str(40 * MiB)]
    proc = subprocess.run([sys.executable, "-c", CHILD, *args], capture_output=True, text=True, env=child_env(),
                          timeout=600)
    assert proc.returncode == 0, proc.stderr
    r = json.loads(proc.stdout.strip().splitlines()[-1])
    assert r["tiles"] > 1  # the limit forced tiles: the whole pair would need ~80 MiB beyond the base
    assert r["peak"] <= r["limit"], f"peak {r['peak'] / MiB:.0f} MiB over the limit {r['limit'] / MiB:.0f} MiB"
