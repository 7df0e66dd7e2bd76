"""Out-of-core M3C2: the core points cut into square XY tiles, each computed from only the points
of both clouds within a halo of its core points, on one machine or as tasks on a Dask cluster.
The merged result is identical, bit for bit and in core-point order, to a single in-memory run
(docs/scaling.md gives the argument).

Steps (:func:`run_tiled`):

1. Core points: every reference point (streamed), the reference subsampled with ``core_spacing``
   (once, globally, streaming, :func:`streaming_subsample`), or a core file.
2. Plan: core point i goes to tile ``(floor((x - x0) / S), floor((y - y0) / S))``; each tile's
   core points are spilled to disk in core order and ``tile_of`` (uint32 per core point) is
   written sequentially. A tile's *box* is its core points' bounding box grown by the halo
   ``h = max(max D / 2, sqrt((d / 2)^2 + max_depth^2))`` (plus a hair) on every axis.
3. Clouds: a COPC input is read per tile with a box query; any other input is streamed once and
   each point appended to the spill file of every tile whose box holds it. Either way a tile's
   points keep the file's relative order.
4. Compute: tile by tile (bounded memory), or as Dask tasks (``retries``), each task reading its
   inputs from paths; per-tile results are spilled to disk by the caller.
5. Merge: ``tile_of`` is streamed and each row taken from its tile's result spill in order, then
   written with :class:`m3c2kit.io.streaming.TableWriter` (temporary file, renamed when complete).
"""
from __future__ import annotations

import contextlib
import functools
import math
import os
import re
import shutil
import tempfile
import time
import uuid
from dataclasses import dataclass, field
from types import SimpleNamespace
from pathlib import Path
from typing import Callable

import numpy as np

from . import api, diagnostics, engine
from .limits import check_tile_size, usable_length
from .errors import CloudWriteError, M3C2Error, UsageError
from .io.atomic import private_folder
from .io.streaming import DEFAULT_CHUNK, PointSource, TableWriter, _in_box
from .io.fields import typed_columns
from .optional import require
from .result import Result
from .settings import engine_params, orientation, resolve

__all__ = ["halo", "run_tiled", "streaming_subsample", "parse_memory", "choose_tile_size", "plan_memory",
           "MemoryPlan", "compute_tile", "TileTask", "TiledReport", "BYTES_PER_POINT", "BYTES_PER_CORE",
           "BASE_BYTES", "STREAM_BYTES_PER_ROW", "MERGE_BYTES_PER_ROW"]

#: Resident bytes per cloud point of a tile while it is computed: 24 B coordinates read from the
#: spill + the engine's octree (24 B slot copy, 4 B index; while it is built an 8 B key, 16 B for
#: a cloud around the grid origin, and the sort's buffers; ~2-4 B nodes, ~3-5 B moments on the
#: normals' cloud), measured at 59-67 B with both indexes built at once; rounded up (docs/scaling.md).
BYTES_PER_POINT = 100
#: Resident bytes per core point of a tile: 24 B coordinates, ~85 B engine result and scratch
#: (measured), the ~150 B row copy spilled to disk, rounded up (docs/scaling.md).
BYTES_PER_CORE = 320
#: The least resident size counted for the interpreter, numpy, laspy, lazrs and the engine module.
BASE_BYTES = 96 * 2**20
#: Added to the resident size measured when the run starts: libraries loaded later (lazrs),
#: allocator slack between the phases.
HEADROOM_BYTES = 48 * 2**20
#: Resident bytes per row of a streaming pass's chunk (core-point plan, halo distribution,
#: subsampling): the reader's record and the coordinates, tile keys, candidate indices and the
#: sorted copy spilled to disk (measured ~250 B in the distribution pass, docs/scaling.md).
STREAM_BYTES_PER_ROW = 320
#: Resident bytes per row of the merge-and-write chunk: the result rows read back, the Result and
#: its output columns, the LAS point record and laspy's temporaries (measured ~600 B for LAZ).
MERGE_BYTES_PER_ROW = 800
#: The smallest chunk a memory limit may ask for (smaller ones only cost time).
MIN_CHUNK = 1 << 14
#: The streaming and merge chunks take at most this share of the memory left beyond the base.
CHUNK_SHARE = 0.25

def halo(params) -> float:
    """Largest distance from a core point to a point that can change its result (the engine's)."""
    return engine.neighbourhood_reach(params)


_UNITS = {"": 1, "b": 1, "k": 1e3, "kb": 1e3, "m": 1e6, "mb": 1e6, "g": 1e9, "gb": 1e9, "t": 1e12, "tb": 1e12,
          "kib": 2**10, "mib": 2**20, "gib": 2**30, "tib": 2**40}


def parse_memory(text) -> int:
    """'2GB' -> 2e9 bytes ('GiB' powers of two, a bare number is bytes)."""
    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+)\s*([a-zA-Z]*)\s*", str(text))
    if not m or m.group(2).lower() not in _UNITS:
        raise UsageError(f"--memory-limit must be a size such as 2GB, 512MiB or 4e9 bytes, got {text!r}")
    value = float(m.group(1)) * _UNITS[m.group(2).lower()]
    if value <= 0:
        raise UsageError(f"--memory-limit must be positive, got {text!r}")
    return int(value)


def choose_tile_size(limit: int, h: float, ref_density: float, cmp_density: float, core_density: float,
                     base: int = BASE_BYTES) -> float:
    """Largest tile side S with base + BYTES_PER_POINT (rho_ref + rho_cmp)(S + 2h)^2 +
    BYTES_PER_CORE rho_core S^2 <= limit (densities in points per unit of area)."""
    budget = limit - base
    a = BYTES_PER_POINT * (ref_density + cmp_density)
    b = BYTES_PER_CORE * core_density

    def need(s):
        return a * (s + 2 * h) ** 2 + b * s * s

    floor_size = max(h, 1e-9) / 4
    if budget <= 0 or need(floor_size) > budget:
        raise UsageError(f"--memory-limit {limit} B is too small: a tile needs at least {base + need(floor_size):.3g} B "
                         f"with a halo of {h:.6g} (docs/scaling.md)")
    lo, hi = floor_size, floor_size
    while need(hi) <= budget and hi < 1e12:
        lo, hi = hi, hi * 2
    for _ in range(60):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if need(mid) <= budget else (lo, mid)
    return lo


@dataclass
class MemoryPlan:
    """How a run under a memory limit spends it. The phases run one after the other, so the peak
    is ``base`` plus the largest of: a streaming chunk (``stream_rows`` x STREAM_BYTES_PER_ROW),
    a merge chunk (``merge_rows`` x MERGE_BYTES_PER_ROW) and one tile (``limit - base``, which
    :func:`choose_tile_size` fills)."""

    limit: int
    base: int
    stream_rows: int
    merge_rows: int

    @property
    def stream_bytes(self) -> int:
        return self.stream_rows * STREAM_BYTES_PER_ROW

    @property
    def merge_bytes(self) -> int:
        return self.merge_rows * MERGE_BYTES_PER_ROW


def _chunk_rows(budget: int, per_row: int, most: int) -> int:
    rows = int(CHUNK_SHARE * budget) // per_row
    return int(max(min(MIN_CHUNK, most), min(most, rows)))


def plan_memory(limit: int, resident: int, chunk_size: int = DEFAULT_CHUNK) -> MemoryPlan:
    """The fixed costs of a run under `limit` bytes with `resident` bytes already in use: base =
    max(BASE_BYTES, resident + HEADROOM_BYTES); the streaming and merge chunks are sized to at most
    CHUNK_SHARE of ``limit - base`` (never more than `chunk_size` rows nor, unless `chunk_size` is
    smaller, fewer than MIN_CHUNK)."""
    base = max(BASE_BYTES, int(resident) + HEADROOM_BYTES)
    budget = limit - base
    least = min(MIN_CHUNK, chunk_size) * max(STREAM_BYTES_PER_ROW, MERGE_BYTES_PER_ROW)
    if budget < least:
        raise UsageError(f"--memory-limit {limit} B is too small: this process already holds {resident / 2**20:.0f} MiB "
                         f"and the run needs at least {(base + least) / 2**20:.0f} MiB (docs/scaling.md)")
    return MemoryPlan(limit=limit, base=base, stream_rows=_chunk_rows(budget, STREAM_BYTES_PER_ROW, chunk_size),
                      merge_rows=_chunk_rows(budget, MERGE_BYTES_PER_ROW, chunk_size))


@functools.lru_cache(maxsize=1)
def _malloc_trim():
    """glibc's malloc_trim, or None where there is no glibc."""
    try:
        import ctypes
        return ctypes.CDLL("libc.so.6").malloc_trim
    except (OSError, AttributeError):
        return None


def _release_memory() -> None:
    """Hands the allocator's free pages back to the system between phases (glibc), so that one
    phase's freed buffers do not stay resident under the next phase's peak."""
    trim = _malloc_trim()
    if trim is not None:
        trim(0)


# --------------------------------------------------------------------------- core points

def streaming_subsample(source: PointSource, spacing: float, chunk_size: int = DEFAULT_CHUNK) -> np.ndarray:
    """The reference subsampled to a minimum spacing, exactly as ``engine.subsample_min_spacing``
    on the whole cloud, in one streaming pass (greedy in file order).

    Each chunk is run through the engine after the already kept points within 2.5 spacings of
    its bounding box, with the cloud's first point (the engine's grid anchor, always kept) first:
    every chunk point is then checked against the same earlier kept points as in the global run,
    and the prefix is kept again entirely (asserted)."""
    spacing = float(spacing)
    kept = np.empty((0, 3))
    first = None
    margin = 2.5 * spacing
    for xyz in source.chunks(chunk_size):
        if first is None:
            first = xyz[:1].copy()
            near = np.empty((0, 3))
        else:
            mask = _in_box(kept, xyz.min(axis=0) - margin, xyz.max(axis=0) + margin)
            mask[0] = False
            near = np.concatenate([first, kept[mask]])
        pts = np.ascontiguousarray(np.concatenate([near, xyz]))
        idx = engine.subsample_min_spacing(pts, spacing, "--core-spacing")
        prefix = len(near)
        if prefix and (len(idx) < prefix or not np.array_equal(idx[:prefix], np.arange(prefix))):
            raise M3C2Error("internal error: streaming subsampling diverged from the global one")
        kept = np.concatenate([kept, pts[idx[idx >= prefix]]])
    return kept


class _CoreStream:
    """Core points in order, in chunks: the reference stream, or an in-memory array."""

    def __init__(self, source: PointSource | None = None, array: np.ndarray | None = None,
                 normals: np.ndarray | None = None):
        self.source, self.array, self.normals = source, array, normals

    def chunks(self, size: int):
        if self.source is not None:
            for xyz in self.source.chunks(size):
                yield xyz, None
        else:
            for start in range(0, len(self.array), size):
                yield self.array[start:start + size], (None if self.normals is None
                                                      else self.normals[start:start + size])


# --------------------------------------------------------------------------------- tasks

@dataclass
class CloudInput:
    """Where a tile's points of one cloud come from: a spill file of float64 xyz in file order,
    or a COPC file and the tile's box."""

    spill: str | None = None
    copc: str | None = None
    lo: tuple = ()
    hi: tuple = ()
    drop_nonfinite: bool = False

    def load(self) -> np.ndarray:
        if self.spill is not None:
            if not os.path.exists(self.spill):
                return np.empty((0, 3))
            return np.fromfile(self.spill, dtype=np.float64).reshape(-1, 3)
        return PointSource(self.copc, drop_nonfinite=self.drop_nonfinite).query_box(self.lo, self.hi)


@dataclass
class TileTask:
    """Everything one tile's computation needs, as paths and numbers (picklable)."""

    tile: int
    n_core: int
    core_path: str
    normals_path: str | None
    reference: CloudInput
    compared: CloudInput
    far_point: tuple  # stands in for an empty cloud: farther than the halo from every core point


def compute_tile(task: TileTask, params, threads: int = 0) -> dict:
    """Runs the engine on one tile; returns its result arrays (engine's names) plus ``tile``,
    ``n`` and ``core`` (the tile's core points, in core order)."""
    core = np.fromfile(task.core_path, dtype=np.float64).reshape(-1, 3)
    if len(core) != task.n_core:
        raise M3C2Error(f"tile {task.tile}: core spill holds {len(core)} points, expected {task.n_core}")
    normals = None
    if task.normals_path is not None:
        normals = np.fromfile(task.normals_path, dtype=np.float64).reshape(-1, 3)
    clouds = []
    for cloud_input in (task.reference, task.compared):
        pts = cloud_input.load()
        # The engine refuses an empty cloud; one point beyond every core point's reach leaves
        # each result as the whole cloud's (no point there either) and keeps the order.
        clouds.append(pts if len(pts) else np.asarray([task.far_point], dtype=np.float64))
    if threads <= 0:
        try:
            from distributed import get_worker
            threads = get_worker().state.nthreads
        except Exception:
            threads = 0
    raw = engine.compute(clouds[0], clouds[1], core, params, normals, threads=int(threads))
    out = dict(raw)
    out.update(tile=task.tile, n=len(core), core=core, n_reference=len(clouds[0]), n_compared=len(clouds[1]))
    return out


_RESULT_KEYS = engine.RESULT_FIELDS


def _result_dtype(out: dict) -> np.dtype:
    fields = [("core", np.float64, (3,))]
    for k in _RESULT_KEYS:
        v = np.asarray(out[k])
        fields.append((k, v.dtype, v.shape[1:]) if v.ndim > 1 else (k, v.dtype))
    return np.dtype(fields)


def _result_rows(out: dict, dtype: np.dtype) -> np.ndarray:
    rows = np.empty(out["n"], dtype=dtype)
    rows["core"] = out["core"]
    for k in _RESULT_KEYS:
        rows[k] = out[k]
    return rows


# -------------------------------------------------------------------------------- report

@dataclass
class TiledReport:
    """What a tiled run did (also printed by the command line)."""

    core_points: int = 0
    tiles: int = 0
    tile_size: float = 0.0
    halo: float = 0.0
    reference_points: int = 0
    compared_points: int = 0
    tile_points_max: int = 0          # largest reference + compared points of one tile
    tile_points_total: int = 0        # sum over tiles (halo points counted once per tile)
    estimated_tile_bytes_max: int = 0
    memory_limit: int | None = None
    memory_plan: MemoryPlan | None = None
    dask: bool = False
    workers: int = 1
    seconds: dict = field(default_factory=dict)
    status_counts: dict = field(default_factory=dict)
    significant: int = 0
    with_distance: int = 0
    result: Result | None = None
    warnings: list = field(default_factory=list)  # m3c2kit.diagnostics' messages, also emitted
    evidence: SimpleNamespace | None = None  # the columns the warnings were drawn from

    def lines(self, output) -> list[str]:
        where = f"Dask cluster ({self.workers} workers)" if self.dask else "one machine"
        out = [f"wrote {output}: {self.core_points} core points, {self.with_distance} with a distance, "
               f"{self.significant} significant changes",
               f"tiled on {where}: {self.tiles} tiles of {self.tile_size:.6g} with a halo of {self.halo:.6g}; "
               f"largest tile {self.tile_points_max} cloud points (estimated {self.estimated_tile_bytes_max / 2**20:.0f} MiB)",
               "status: " + ", ".join(f"{k} {v}" for k, v in self.status_counts.items())]
        return out


# ----------------------------------------------------------------------------------- run

@contextlib.contextmanager
def _spill_file(path, mode: str):
    """Every spill write of a tiled run goes through here: an OSError (a full disk, a file size
    limit) becomes a CloudWriteError naming the folder the spills live in (the private work folder
    beside the output, docs/errors.md "Output") and the problem, instead of a traceback."""
    try:
        with open(path, mode) as f:
            yield f
    except OSError as e:
        folder = Path(path).parent.parent
        raise CloudWriteError(f"{folder}: cannot write the tiled run's spill files (kept in a work folder there "
                              f"until the run ends): {e.strerror or e}") from None


def _put(f, array: np.ndarray) -> None:
    """Writes an array's bytes (not tofile(): its short write raises an OSError without errno)."""
    f.write(np.ascontiguousarray(array).reshape(-1).view(np.uint8).data)


class _Spills:
    """Per-tile append-only binary files in one directory."""

    def __init__(self, directory: Path, stem: str):
        self.directory, self.stem = directory, stem

    def path(self, tile: int) -> str:
        return str(self.directory / f"{self.stem}-{tile}.bin")

    def append(self, tiles: np.ndarray, rows: np.ndarray) -> None:
        """Appends rows[i] to tile tiles[i]'s file, keeping the rows' order within each tile."""
        if len(tiles) == 0:
            return
        order = np.argsort(tiles, kind="stable")
        tiles, rows = tiles[order], rows[order]
        cuts = np.flatnonzero(np.diff(tiles)) + 1
        starts = np.concatenate([[0], cuts])
        stops = np.concatenate([cuts, [len(tiles)]])
        for a, b in zip(starts, stops):
            with _spill_file(self.path(int(tiles[a])), "ab") as f:
                _put(f, rows[a:b])


def _density(source: PointSource, chunk_size: int) -> tuple[int, float]:
    """(points, points per unit of XY area) from the LAS header, or a streaming pass."""
    if source.kind in ("las", "copc"):
        import laspy
        with laspy.open(source.path) as r:
            h = r.header
            n, lo, hi = int(h.point_count), np.asarray(h.mins), np.asarray(h.maxs)
    else:
        n, lo, hi = 0, np.full(3, np.inf), np.full(3, -np.inf)
        for xyz in source.chunks(chunk_size):
            n += len(xyz)
            lo, hi = np.minimum(lo, xyz.min(axis=0)), np.maximum(hi, xyz.max(axis=0))
    area = max(float((hi[0] - lo[0]) * (hi[1] - lo[1])), 1e-12) if n else 1.0
    return n, n / area


def _rss_bytes() -> int:
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 0


def run_tiled(reference, compared, *, output=None, core=None, core_spacing=None, core_normals=None,
              normal_scale=None, projection_scale, max_depth, tile_size=None, memory_limit=None,
              dask_scheduler=None, client=None, threads: int = 0, work_dir=None, projected: bool = False,
              position: str = "core", drop_nonfinite: bool = False, return_result: bool = False,
              chunk_size: int = DEFAULT_CHUNK, retries: int = 3, task_fn: Callable | None = None,
              log: Callable[[str], object] | None = None, **params) -> TiledReport:
    """Tiled M3C2 between the files `reference` and `compared` (paths, or PointSource).

    `core`: None (every reference point), a core file path, or an (N, 3) array; or
    `core_spacing`. `tile_size` S (XY side of a tile) or `memory_limit` (bytes or '2GB': S is
    chosen so a tile's estimated resident memory fits). `dask_scheduler` (an address) or `client`
    (a distributed.Client) runs tiles as Dask tasks with `retries`. `output`: a file written
    atomically (same bytes as the untiled run); `return_result` also gathers the Result in
    memory. Other keywords are :func:`m3c2kit.api.compare`'s engine parameters.
    """
    t_start = time.perf_counter()
    log = log or (lambda s: None)
    report = TiledReport()
    read_points = params.pop("read_points", None)
    given = dict(params, normal_scale=normal_scale, projection_scale=projection_scale, max_depth=max_depth)
    values = resolve(given, "compare", api=True)
    engine_p = engine_params(values, "compare", read_points, core_points=orientation.LATER)
    if engine_p.normal_subsample_spacing > 0:
        raise UsageError("--normal-subsample cannot be combined with tiling (--tile-size, --memory-limit, "
                         "--dask-scheduler): the subsampled normal cloud depends on the whole cloud's order, "
                         "so tiles would not reproduce the untiled result")
    if values["lod"] == "bootstrap":
        raise UsageError("--bootstrap cannot be combined with tiling: the bootstrap stream is seeded by the "
                         "core point's index in the run, which a tile does not know")
    if values.get("classifier") is not None or values.get("keep") is not None:
        raise UsageError("--classifier / --keep run in memory only: a tile would classify its points without "
                         "the neighbourhoods beyond its halo; drop --tile-size, --memory-limit and "
                         "--dask-scheduler, or classify first (m3c2 classify apply) and compare the kept points")
    if values["uncertainty"] != "eq1":
        raise UsageError(f"--uncertainty {values['uncertainty']} runs in memory only: tiled and Dask runs do not "
                         "carry the per-point fields it reads (precisions, scan-position ids); drop --tile-size, "
                         "--memory-limit and --dask-scheduler")
    if tile_size is None and memory_limit is None:
        raise UsageError("tiling needs --tile-size or --memory-limit")
    h = halo(engine_p)
    hp = engine.tile_halo(engine_p)
    report.halo = h
    if tile_size is not None:  # before any file is read (docs/errors.md, "Run limits")
        tile_size = usable_length("--tile-size", tile_size)
        check_tile_size(tile_size, h)

    ref_src = reference if isinstance(reference, PointSource) else PointSource(reference, drop_nonfinite=drop_nonfinite)
    cmp_src = compared if isinstance(compared, PointSource) else PointSource(compared, drop_nonfinite=drop_nonfinite)

    # memory plan: the fixed costs (what this process holds, the streaming and merge chunks)
    limit = plan = None
    stream_rows = merge_rows = chunk_size
    if memory_limit is not None:
        limit = parse_memory(memory_limit) if not isinstance(memory_limit, (int, float)) else int(memory_limit)
        report.memory_limit = limit
        plan = plan_memory(limit, _rss_bytes(), chunk_size)
        stream_rows = plan.stream_rows

    # 1. core points
    normals_arr = None
    if values["normal_source"] == "core":
        if core_normals is None:
            raise UsageError("--normal-source core needs core_normals (one normal per core point)")
        normals_arr = api.as_points("core_normals", core_normals)
    if core is not None and core_spacing is not None:
        raise UsageError("give either core points (--core) or --core-spacing, not both")
    if core is not None:
        if isinstance(core, (str, os.PathLike)):
            from .io import read_cloud
            core = read_cloud(core, drop_nonfinite=drop_nonfinite)
        core_arr = api.as_points("core_points", core)
        cores = _CoreStream(array=core_arr, normals=normals_arr)
    elif core_spacing is not None:
        t0 = time.perf_counter()
        core_arr = streaming_subsample(ref_src, api.positive("--core-spacing", core_spacing), stream_rows)
        report.seconds["core_subsample"] = time.perf_counter() - t0
        cores = _CoreStream(array=core_arr, normals=normals_arr)
    else:
        core_arr = None
        cores = _CoreStream(source=ref_src, normals=None)
    if normals_arr is not None and (core_arr is None or len(normals_arr) != len(core_arr)):
        raise UsageError("core_normals must have one row per core point")
    if orientation.needs_core_points(values["orient"]):  # their barycentre, the same bits as in memory
        engine_p = engine_params(values, "compare", read_points,
                                 core_points=lambda: (xyz for xyz, _ in cores.chunks(stream_rows)))

    # Tiles are anchored at the core points' lowest x and y where that is known without a pass
    # (any anchor gives the same results): a tile as large as the survey is then one tile.
    extent = None  # the core points' XY extent, where known
    if core_arr is not None and len(core_arr):
        origin = core_arr[:, :2].min(axis=0)
        extent = core_arr[:, :2].max(axis=0) - origin
    elif ref_src.kind in ("las", "copc"):
        import laspy
        with laspy.open(ref_src.path) as r:
            origin = np.asarray(r.header.mins, dtype=np.float64)[:2]
            extent = np.asarray(r.header.maxs, dtype=np.float64)[:2] - origin
    else:
        origin = None  # the first core point

    # tile size; the plan again, now that the core points are held
    if plan is not None:
        plan = plan_memory(limit, _rss_bytes(), chunk_size)
        stream_rows, merge_rows = plan.stream_rows, plan.merge_rows
        report.memory_plan = plan
    if tile_size is None:
        n_ref, rho_ref = _density(ref_src, stream_rows)
        _, rho_cmp = _density(cmp_src, stream_rows)
        if core_arr is None:
            rho_core = rho_ref
        else:
            span = core_arr.max(axis=0) - core_arr.min(axis=0) if len(core_arr) else np.ones(3)
            rho_core = len(core_arr) / max(float(span[0] * span[1]), 1e-12)
        tile_size = choose_tile_size(limit, h, rho_ref, rho_cmp, rho_core, base=plan.base)
        per_axis = np.maximum(np.ceil(extent / tile_size), 1) if extent is not None else np.ones(2)
        if per_axis.max() >= 2:
            # As many tiles per axis, all of one size: the smallest side that needs no more
            # (at least half the chosen one); smaller tiles only lower the peak.
            tile_size = min(tile_size, float((extent / per_axis).max()) * (1 + 1e-9))
        log(f"--memory-limit {limit} B: tile size {tile_size:.6g}")
    if plan is not None:
        log(f"memory plan: base {plan.base / 2**20:.0f} MiB, streaming chunks of {plan.stream_rows} rows, "
            f"merge chunks of {plan.merge_rows} rows")
    size = float(tile_size)
    report.tile_size = size

    own_dir = work_dir is None
    if own_dir:
        parent = Path(output).resolve().parent if output is not None else None
        work = private_folder(parent if parent is not None else Path(tempfile.gettempdir()))
    else:
        work = Path(work_dir)
        work.mkdir(parents=True, exist_ok=True)
    try:
        return _run_in(work, report, ref_src, cmp_src, cores, normals_arr is not None, size, hp, engine_p,
                       output=output, dask_scheduler=dask_scheduler, client=client, threads=threads,
                       projected=projected, position=position, return_result=return_result,
                       origin=origin, stream_rows=stream_rows, merge_rows=merge_rows, retries=retries,
                       task_fn=task_fn or compute_tile, log=log,
                       record=api.run_record(given, engine_p), t_start=t_start, values=values)
    finally:
        if own_dir:
            shutil.rmtree(work, ignore_errors=True)


def _plan_tiles(work: Path, cores: _CoreStream, core_spill: "_Spills", normal_spill: "_Spills", size: float,
                origin, rows: int):
    """Tile of every core point (``tile_of.u32``), per-tile core (and normal) spills, bounding
    boxes and counts. Returns (ids, lo, hi, counts, origin, n_core)."""
    ids: dict[tuple[int, int], int] = {}
    lo_l: list = []
    hi_l: list = []
    count_l: list = []
    n_core = 0
    with _spill_file(work / "tile_of.u32", "wb") as tile_of:
        for xyz, nrm in cores.chunks(rows):
            if origin is None:
                origin = xyz[0, :2].copy()
            keys = np.floor((xyz[:, :2] - origin) / size).astype(np.int64)
            uniq, inverse = np.unique(keys, axis=0, return_inverse=True)
            del keys
            inverse = inverse.reshape(-1)
            local = np.empty(len(uniq), dtype=np.uint32)
            for j, k in enumerate(map(tuple, uniq.tolist())):
                if k not in ids:
                    ids[k] = len(ids)
                    lo_l.append(np.full(3, np.inf))
                    hi_l.append(np.full(3, -np.inf))
                    count_l.append(0)
                local[j] = ids[k]
            tid = local[inverse]
            _put(tile_of, tid)
            for j in range(len(uniq)):
                t = int(local[j])
                pts = xyz[inverse == j]
                lo_l[t] = np.minimum(lo_l[t], pts.min(axis=0))
                hi_l[t] = np.maximum(hi_l[t], pts.max(axis=0))
                count_l[t] += len(pts)
            core_spill.append(tid, xyz)
            if nrm is not None:
                normal_spill.append(tid, np.ascontiguousarray(nrm, dtype=np.float64))
            n_core += len(xyz)
    return ids, np.array(lo_l).reshape(-1, 3), np.array(hi_l).reshape(-1, 3), np.array(count_l, dtype=np.int64), \
        origin, n_core


def _distribute(src: PointSource, spill: "_Spills", ids: dict, lo, hi, origin, size: float, hp: float,
                rows: int) -> int:
    """Streams one cloud once, appending each point to the spill of every tile whose box (lo, hi,
    halo included) holds it, in file order within each tile. Returns the points read."""
    karr = np.array(list(ids.keys()), dtype=np.int64)
    kmin, kmax = karr.min(axis=0), karr.max(axis=0)
    key_of = np.full(tuple(kmax - kmin + 1), -1, dtype=np.int64)
    key_of[karr[:, 0] - kmin[0], karr[:, 1] - kmin[1]] = np.array(list(ids.values()))
    reach = int(math.floor(2 * hp / size)) + 2
    total = 0
    for xyz in src.chunks(rows):
        total += len(xyz)
        base = np.floor((xyz[:, :2] - hp - origin) / size).astype(np.int64) - kmin
        top = np.floor((xyz[:, :2] + hp - origin) / size).astype(np.int64) - kmin
        sel_t, sel_i = [], []
        for dx in range(reach):
            for dy in range(reach):
                kx, ky = base[:, 0] + dx, base[:, 1] + dy
                ok = (kx <= top[:, 0]) & (ky <= top[:, 1]) & (kx >= 0) & (ky >= 0) \
                    & (kx < key_of.shape[0]) & (ky < key_of.shape[1])
                idx = np.flatnonzero(ok)
                t = key_of[kx[idx], ky[idx]]
                del kx, ky, ok
                keep = t >= 0
                idx, t = idx[keep], t[keep]
                p = xyz[idx]
                inside = ((p[:, 0] >= lo[t, 0]) & (p[:, 0] <= hi[t, 0]) & (p[:, 1] >= lo[t, 1])
                          & (p[:, 1] <= hi[t, 1]) & (p[:, 2] >= lo[t, 2]) & (p[:, 2] <= hi[t, 2]))
                del p
                sel_t.append(t[inside])
                sel_i.append(idx[inside])
        del base, top
        t_all, i_all = np.concatenate(sel_t), np.concatenate(sel_i)
        del sel_t, sel_i
        # Within a tile, points must keep file order: sort by (tile, index in chunk).
        order = np.lexsort((i_all, t_all))
        spill.append(t_all[order], xyz[i_all[order]])
        del t_all, i_all, order
    return total


def _run_in(work: Path, report: TiledReport, ref_src, cmp_src, cores: _CoreStream, with_normals: bool, size: float,
            hp: float, engine_p, *, output, dask_scheduler, client, threads, projected, position,
            return_result, origin, stream_rows, merge_rows, retries, task_fn, log, record, t_start,
            values) -> TiledReport:
    # Each phase runs in its own function, so that its buffers are gone (and handed back to the
    # system, _release_memory) before the next phase's peak.
    # 2. plan: tile of every core point, per-tile core spills and bounding boxes
    t0 = time.perf_counter()
    core_spill, normal_spill = _Spills(work, "core"), _Spills(work, "normals")
    ids, lo, hi, counts, origin, n_core = _plan_tiles(work, cores, core_spill, normal_spill, size, origin, stream_rows)
    n_tiles = len(ids)
    report.core_points, report.tiles = n_core, n_tiles
    if n_core == 0:
        raise UsageError("no core points")
    lo -= hp  # each tile's box: its core points' bounding box grown by the halo
    hi += hp
    _release_memory()
    report.seconds["plan"] = time.perf_counter() - t0
    log(f"{n_core} core points in {n_tiles} tiles of {size:.6g} (halo {hp:.6g})")

    # 3. clouds: spill non-COPC inputs into every tile box that holds each point
    t0 = time.perf_counter()
    n_points = {}
    spills = {}
    for name, src in (("reference", ref_src), ("compared", cmp_src)):
        if src.kind == "copc":
            spills[name] = None
            continue
        spills[name] = _Spills(work, name)
        n_points[name] = _distribute(src, spills[name], ids, lo, hi, origin, size, hp, stream_rows)
        _release_memory()
    report.reference_points = n_points.get("reference", 0)
    report.compared_points = n_points.get("compared", 0)
    report.seconds["distribute"] = time.perf_counter() - t0

    def cloud_input(name, src, t):
        if spills[name] is None:
            return CloudInput(copc=str(src.path), lo=tuple(lo[t]), hi=tuple(hi[t]), drop_nonfinite=src.drop_nonfinite)
        return CloudInput(spill=spills[name].path(t))

    far = hi.max(axis=0) + 4 * hp + 1.0
    tasks = [TileTask(tile=t, n_core=int(counts[t]), core_path=core_spill.path(t),
                      normals_path=normal_spill.path(t) if with_normals else None,
                      reference=cloud_input("reference", ref_src, t), compared=cloud_input("compared", cmp_src, t),
                      far_point=tuple(float(v) for v in far)) for t in range(n_tiles)]

    # 4. compute: per-tile results spilled to disk, each tile exactly once
    t0 = time.perf_counter()
    result_spill = _Spills(work, "result")
    state = {"dtype": None, "done": set(), "tile_points_max": 0, "tile_points_total": 0}

    def accept(out: dict) -> None:
        t = int(out["tile"])
        if t in state["done"]:
            raise M3C2Error(f"tile {t} returned twice")
        if out["n"] != counts[t]:
            raise M3C2Error(f"tile {t} returned {out['n']} rows for {counts[t]} core points")
        if state["dtype"] is None:
            state["dtype"] = _result_dtype(out)
        rows = _result_rows(out, state["dtype"])
        with _spill_file(result_spill.path(t), "wb") as f:
            _put(f, rows)
        state["done"].add(t)
        pts = int(out["n_reference"]) + int(out["n_compared"])
        state["tile_points_max"] = max(state["tile_points_max"], pts)
        state["tile_points_total"] += pts

    if dask_scheduler is not None or client is not None:
        report.dask = True
        _run_dask(tasks, engine_p, threads, retries, task_fn, accept, dask_scheduler, client, report, log)
    else:
        for i, task in enumerate(tasks):
            accept(task_fn(task, engine_p, threads))
            _release_memory()
            if (i + 1) % max(1, n_tiles // 20) == 0:
                log(f"tile {i + 1}/{n_tiles}")
    if len(state["done"]) != n_tiles:
        raise M3C2Error(f"only {len(state['done'])} of {n_tiles} tiles were computed")
    report.tile_points_max = state["tile_points_max"]
    report.tile_points_total = state["tile_points_total"]
    base = report.memory_plan.base if report.memory_plan is not None else BASE_BYTES
    report.estimated_tile_bytes_max = int(base + BYTES_PER_POINT * report.tile_points_max
                                          + BYTES_PER_CORE * int(counts.max()))
    report.seconds["compute"] = time.perf_counter() - t0

    # 5. merge in core order and write
    _release_memory()
    t0 = time.perf_counter()
    _merge(work, result_spill, state["dtype"], counts, n_core, report, output=output, like=ref_src.like(),
           projected=projected, position=position, return_result=return_result, chunk_size=merge_rows,
           record=record)
    report.seconds["merge_write"] = time.perf_counter() - t0
    report.warnings = diagnostics.warn(report.evidence, values)  # the same as an in-memory run's
    report.seconds["total"] = time.perf_counter() - t_start
    return report


#: Seconds to reach a Dask scheduler and complete its handshake: an address that accepts and never
#: answers waited forever, a closed local port took 30 s (distributed's default) to say so.
DASK_CONNECT_TIMEOUT = 10.0


def _connect(Client, address: str):
    """A distributed.Client of `address`, every wait bounded by DASK_CONNECT_TIMEOUT, or an
    M3C2Error naming --dask-scheduler: refused at once when nothing listens (a TCP probe before
    distributed's retries), a timeout when the address accepts but never answers, and a clear
    message when something other than a Dask scheduler answers (its bytes read as a message
    length made "Unable to allocate 3.07 EiB")."""
    import socket
    where = str(address).split("://", 1)[-1]
    host, _, port = where.rpartition(":")
    if host and port.isdigit():
        _probe_scheduler(address, host.strip("[]"), int(port))
    try:
        return Client(address, timeout=DASK_CONNECT_TIMEOUT)
    except (MemoryError, OverflowError, ValueError, TypeError) as e:
        raise M3C2Error(f"--dask-scheduler {address}: the service there did not answer as a Dask scheduler "
                        f"({type(e).__name__}); check the address and port") from None
    except Exception as e:  # noqa: BLE001 - timeouts and every other connection failure are the address's
        raise M3C2Error(f"--dask-scheduler {address}: no answer from a Dask scheduler within "
                        f"{DASK_CONNECT_TIMEOUT:g} s ({type(e).__name__}: {e})") from None


#: A Dask scheduler opens every connection with its handshake: one message whose first 8 bytes
#: are its length (uint64, little-endian; ~60 bytes). Longer than this is not a scheduler.
_DASK_HANDSHAKE_MAX = 2**26


def _probe_scheduler(address: str, host: str, port: int) -> None:
    """Connects to (host, port) and reads the first 8 bytes a Dask scheduler sends, within
    DASK_CONNECT_TIMEOUT; an M3C2Error naming --dask-scheduler when that fails."""
    import socket
    import struct
    try:
        conn = socket.create_connection((host, port), timeout=DASK_CONNECT_TIMEOUT)
    except ConnectionRefusedError:
        raise M3C2Error(f"--dask-scheduler {address}: connection refused (no scheduler listens there)") from None
    except OSError as e:
        raise M3C2Error(f"--dask-scheduler {address}: cannot connect: {e.strerror or e}") from None
    with conn:
        head = b""
        try:
            while len(head) < 8:
                chunk = conn.recv(8 - len(head))
                if not chunk:
                    break
                head += chunk
        except OSError:  # socket.timeout among them
            raise M3C2Error(f"--dask-scheduler {address}: no answer within {DASK_CONNECT_TIMEOUT:g} s: the address "
                            f"accepts connections but no Dask scheduler speaks there") from None
    if len(head) < 8 or not 0 < struct.unpack("<Q", head)[0] <= _DASK_HANDSHAKE_MAX:
        raise M3C2Error(f"--dask-scheduler {address}: the service there did not answer as a Dask scheduler "
                        f"(first bytes {head!r}); check the address and port")


def _run_dask(tasks, engine_p, threads, retries, task_fn, accept, address, client, report, log) -> None:
    distributed = require("distributed", extra="dask", purpose="running on a Dask cluster (--dask-scheduler)")
    Client, as_completed = distributed.Client, distributed.as_completed
    own = client is None
    if own:
        client = _connect(Client, address)
    try:
        report.workers = max(1, len(client.scheduler_info().get("workers", {})))
        run_id = uuid.uuid4().hex[:8]
        window = max(2, 2 * report.workers)
        pending = iter(tasks)
        futures = as_completed(with_results=True)

        def submit_next() -> bool:
            task = next(pending, None)
            if task is None:
                return False
            futures.add(client.submit(task_fn, task, engine_p, threads, key=f"m3c2-tile-{run_id}-{task.tile}",
                                      retries=retries, pure=False))
            return True

        for _ in range(window):
            if not submit_next():
                break
        done = 0
        for future, out in futures:
            accept(out)
            future.release()
            done += 1
            if done % max(1, len(tasks) // 20) == 0:
                log(f"tile {done}/{len(tasks)}")
            submit_next()
    finally:
        if own:
            client.close()


#: The columns m3c2kit.diagnostics reads, gathered over the tiles (about 17 B per core point).
_EVIDENCE = ("status", "n1", "n2", "normal_scale", "roughness")


def _output_xyz(chunk: Result, projected: bool, position: str) -> np.ndarray:
    table = chunk.columns(projected=projected, position=position)
    return np.column_stack([table["x"], table["y"], table["z"]])


def _merge(work: Path, result_spill: _Spills, dtype: np.dtype, counts, n_core: int, report: TiledReport, *,
           output, like, projected, position, return_result, chunk_size, record) -> None:
    def chunks():
        offsets = np.zeros(len(counts), dtype=np.int64)
        taken = np.zeros(len(counts), dtype=np.int64)
        with open(work / "tile_of.u32", "rb") as f:
            while True:
                tid = np.fromfile(f, dtype=np.uint32, count=chunk_size)
                if len(tid) == 0:
                    break
                rows = np.empty(len(tid), dtype=dtype)
                for t in np.unique(tid):
                    sel = tid == t
                    c = int(sel.sum())
                    part = np.fromfile(result_spill.path(int(t)), dtype=dtype, count=c,
                                       offset=int(offsets[t]) * dtype.itemsize)
                    if len(part) != c:
                        raise M3C2Error(f"tile {t}: result spill is short")
                    rows[sel] = part
                    offsets[t] += c
                    taken[t] += c
                raw = {k: rows[k] for k in _RESULT_KEYS}
                chunk = Result.from_engine(np.ascontiguousarray(rows["core"]), raw, record)
                del rows, raw  # one chunk alive at a time: the caller drops it before the next
                yield chunk
                del chunk
        if not np.array_equal(taken, counts):
            raise M3C2Error("core-point bookkeeping failed: rows taken per tile differ from the plan")

    xyz_min = xyz_max = None
    if output is not None and (like is None or like.scale is None):
        xyz_min, xyz_max = np.full(3, np.inf), np.full(3, -np.inf)
        for chunk in chunks():
            # fmin/fmax: rows without a projection (--position reference|compared) have NaN coordinates.
            xyz = _output_xyz(chunk, projected, position)
            xyz_min = np.fmin(xyz_min, np.fmin.reduce(xyz, axis=0, initial=np.inf))
            xyz_max = np.fmax(xyz_max, np.fmax.reduce(xyz, axis=0, initial=-np.inf))
            del chunk, xyz
    gathered = []
    evidence = {k: [] for k in _EVIDENCE}
    status = np.zeros(256, dtype=np.int64)
    rows_written = 0

    def consume(chunk: Result, writer=None):
        nonlocal rows_written
        rows_written += len(chunk)
        status[:] += np.bincount(chunk.status, minlength=256)
        report.significant += int(chunk.significant.sum())
        report.with_distance += int(np.isfinite(chunk.distance).sum())
        for k in _EVIDENCE:
            evidence[k].append(np.asarray(getattr(chunk, k)))
        if writer is not None:
            table = chunk.columns(projected=projected, position=position)
            xyz = np.column_stack([table.pop("x"), table.pop("y"), table.pop("z")])
            writer.write(xyz, typed_columns(table, las=writer.mode == "las"))  # the stored types of m3c2kit.write
            del xyz, table
        if return_result:
            gathered.append(chunk)

    if output is not None:
        with TableWriter(output, like=like, xyz_min=xyz_min, xyz_max=xyz_max) as writer:
            for chunk in chunks():
                consume(chunk, writer)
                del chunk
    else:
        for chunk in chunks():
            consume(chunk)
            del chunk
    if rows_written != n_core:
        raise M3C2Error(f"wrote {rows_written} rows for {n_core} core points")
    report.evidence = SimpleNamespace(**{k: np.concatenate(v) for k, v in evidence.items()})
    from .result import STATUS_NAMES
    report.status_counts = {STATUS_NAMES[c]: int(n) for c, n in enumerate(status) if n}
    if return_result:
        arrays = {k: np.concatenate([getattr(c, k) for c in gathered]) for k in ("core",) + _RESULT_KEYS}
        core_xyz = arrays.pop("core")
        report.result = Result(core=core_xyz, params=record, **arrays)
