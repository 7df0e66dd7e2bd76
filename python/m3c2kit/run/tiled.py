"""Executing a plan in tiles (out of core), on this machine or as tasks on a Dask cluster. The
merged result is identical, bit for bit and in core-point order, to the in-memory run of the same
plan (docs/scaling.md gives the argument).

Steps (:func:`run_tiled`), each bounded in memory:

0. Checks before any work: the plan (m3c2kit.run.plan, the in-memory run's checks), the tile
   size against the halo, the Dask scheduler reached (bounded in time, m3c2kit.run.dask).
1. With --classifier: each cloud classified tile by tile, then read through its keep mask
   (m3c2kit.run.vegetation).
2. Core points: every reference point (streamed), the reference subsampled with ``core_spacing``
   (once, globally, streaming, :func:`m3c2kit.run.cores.streaming_subsample`), or a core file.
3. Partition (m3c2kit.run.partition): the tile of every core point, per-tile core spills; each
   cloud streamed once into every tile box (core points' box + halo) that holds its points, with
   the per-point inputs it carries (--uncertainty pm precisions, ep scan-position ids). A COPC
   input is read per tile with a box query instead when it carries nothing.
4. Compute: tile by tile, or as Dask tasks (``retries``), each task reading its inputs from paths
   and making the in-memory run's engine call (m3c2kit.run.tasks); results spilled to disk.
5. Merge (m3c2kit.run.merge) in core order, written atomically with the in-memory writer's columns.

Every spill write goes through m3c2kit.run.spill.SpillFolder (a failed write is one clean error);
the spill folder is removed whatever happens.
"""
from __future__ import annotations

import os
import tempfile
import time
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from . import diagnostics, uncertainty_inputs
from .. import engine
from ..base.errors import M3C2Error, UsageError
from ..base.fault_hook import checkpoint as fault_checkpoint
from ..io.arrays import bounds
from ..io.atomic import private_folder
from ..io.streaming import DEFAULT_CHUNK, PointSource
from ..settings.limits import check_halo, check_tile_size, usable_length
from ..settings import engine_params, orientation
from ..settings.parsers import positive
from . import dask as dask_run
from .checks import as_points, check_all_fields, check_core_normals
from .cores import streaming_subsample
from .memory import (BASE_BYTES, BYTES_PER_CORE, BYTES_PER_POINT, choose_tile_size, density, parse_memory,
    plan_memory, release_memory, rss_bytes)
from .merge import Storage, merge
from .outcome import TiledReport
from .partition import CoreStream, Tiles, distribute, plan_tiles
from .plan import Plan, make_plan
from .spill import SpillFolder
from .tasks import CloudInput, TileTask, compute_tile, result_dtype, result_rows
from .vegetation import classify_tiled


def run_tiled(reference, compared, *, output=None, core=None, core_spacing=None, core_normals=None,
              normal_scale=None, projection_scale, max_depth, tile_size=None, memory_limit=None,
              dask_scheduler=None, client=None, threads: int = 0, work_dir=None, projected: bool = False,
              position: str = "core", field_names: str = "m3c2", float64: bool = False,
              all_fields: bool = False, drop_nonfinite: bool = False, return_result: bool = False, chunk_size: int = DEFAULT_CHUNK,
              retries: int = 3, task_fn: Callable | None = None, log: Callable[[str], object] | None = None,
              **params) -> TiledReport:
    """Tiled M3C2 between the files `reference` and `compared` (paths, or PointSource).

    `core`: None (every reference point), a core file path, or an (N, 3) array; or
    `core_spacing`. `tile_size` S (XY side of a tile) or `memory_limit` (bytes or '2GB': S is
    chosen so a tile's estimated resident memory fits). `dask_scheduler` (an address) or `client`
    (a distributed.Client) runs tiles as Dask tasks with `retries`. `output`: a file written
    atomically (same bytes as the untiled run; `field_names`, `float64` and `all_fields` as m3c2kit.write's);
    `return_result` also gathers the Result in memory. Other keywords are
    :func:`m3c2kit.compare`'s parameters, every one of them in every mode.
    """
    t_start = time.perf_counter()
    log = log or (lambda s: None)
    report = TiledReport()
    read_points = params.pop("read_points", None)
    vegetation = params.pop("vegetation", None)  # --classifier / --keep (m3c2kit.classify.vegetation)
    given = dict(params, normal_scale=normal_scale, projection_scale=projection_scale, max_depth=max_depth)
    plan, h, hp, tile_size, limit = preflight(given, tile_size, memory_limit, read_points, vegetation)
    check_core_normals(plan.values, core_normals)
    check_all_fields(output, all_fields)
    report.halo = h
    report.memory_limit = limit

    own_client = client is None and dask_scheduler is not None
    if own_client:
        client = dask_run.connect(dask_scheduler)  # bounded in time, before any file is read
    own_dir = work_dir is None
    try:
        ref_src = reference if isinstance(reference, PointSource) else PointSource(reference,
                                                                                   drop_nonfinite=drop_nonfinite)
        cmp_src = compared if isinstance(compared, PointSource) else PointSource(compared, drop_nonfinite=drop_nonfinite)
        shared = uncertainty_inputs.shared_inputs(plan.values, ref_src.like(), cmp_src.like())
        with ExitStack() as held:
            if own_dir:
                parent = Path(output).resolve().parent if output is not None else None
                work = held.enter_context(private_folder(parent if parent is not None else Path(tempfile.gettempdir())))
                fault_checkpoint("staging")  # a testing aid (docs/errors.md, "Interruption"): spill folder made
                # Dask workers (other processes) reach the folder only by its name; this process
                # writes through the pinned path whatever happens (run/spill.py).
                spills = SpillFolder(work.path, work.directory,
                                     work.directory / work.name if client is not None else None)
            else:
                Path(work_dir).mkdir(parents=True, exist_ok=True)
                spills = SpillFolder(Path(work_dir))
            options = TiledOptions(core=core, core_spacing=core_spacing, core_normals=core_normals,
                                   tile_size=tile_size, limit=limit, threads=threads, output=output,
                                   projected=projected, position=position,
                                   storage=Storage(field_names, float64, all_fields), drop_nonfinite=drop_nonfinite,
                                   return_result=return_result, chunk_size=chunk_size, retries=retries,
                                   task_fn=task_fn or compute_tile, log=log, read_points=read_points)
            report = _run(plan, report, ref_src, cmp_src, spills, shared, h, hp, client, options)
            report.seconds["total"] = time.perf_counter() - t_start
            return report
    finally:
        if own_client:
            client.close()

@dataclass(frozen=True)
class TiledOptions:
    """What a tiled run is asked beside its plan: run_tiled's keywords (documented there)."""
    core: object = None
    core_spacing: float | None = None
    core_normals: object = None
    tile_size: float | None = None
    limit: int | None = None  # the memory limit in bytes
    threads: int = 0
    output: object = None
    projected: bool = False
    position: str = "core"
    storage: Storage = Storage()
    drop_nonfinite: bool = False
    return_result: bool = False
    chunk_size: int = DEFAULT_CHUNK
    retries: int = 3
    task_fn: Callable = compute_tile
    log: Callable[[str], object] = lambda s: None
    read_points: Callable | None = None


def preflight(params: dict, tile_size=None, memory_limit=None, read_points=None, vegetation=None):
    """The checks of a tiled run that need no file (docs/errors.md, "Run limits"): the plan, the
    options tiles cannot reproduce, the tile size against the halo, the memory limit. Returns
    (plan, reach h, tile halo, tile size, memory limit in bytes)."""
    plan = make_plan(params, read_points, vegetation=vegetation)
    values, engine_p = plan.values, plan.engine
    if engine_p.normal_subsample_spacing > 0:
        raise UsageError("--normal-subsample cannot be combined with tiling (--tile-size, --memory-limit, "
                         "--dask-scheduler): the subsampled normal cloud depends on the whole cloud's order, "
                         "so tiles would not reproduce the untiled result")
    if values["lod"] == "bootstrap":
        raise UsageError("--bootstrap cannot be combined with tiling: the bootstrap stream is seeded by the "
                         "core point's index in the run, which a tile does not know")
    if tile_size is None and memory_limit is None:
        raise UsageError("tiling needs --tile-size or --memory-limit")
    h = engine.neighbourhood_reach(engine_p)
    check_halo(h)
    if tile_size is not None:
        tile_size = usable_length("--tile-size", tile_size)
        check_tile_size(tile_size, h)
    limit = None
    if memory_limit is not None:
        limit = parse_memory(memory_limit) if not isinstance(memory_limit, (int, float)) else int(memory_limit)
    return plan, h, engine.tile_halo(engine_p), tile_size, limit


def _executor(client, retries: int, log, report: TiledReport):
    """execute(tasks, fn, accept, args): every task computed once, on this machine one at a time
    (memory handed back between tiles) or on the Dask client; each result handed to accept()."""
    def execute(tasks, fn, accept, args=()) -> None:
        if client is not None:
            report.dask = True
            report.workers = dask_run.run_on_dask(client, tasks, fn, accept, retries=retries, log=log, args=args)
            return
        for i, task in enumerate(tasks):
            accept(fn(task, *args))
            release_memory()
            if (i + 1) % max(1, len(tasks) // 20) == 0:
                log(f"tile {i + 1}/{len(tasks)}")
    return execute


def _run(plan: Plan, report: TiledReport, ref_src, cmp_src, spills: SpillFolder, shared: dict, h: float, hp: float,
         client, options: TiledOptions) -> TiledReport:
    values, engine_p = plan.values, plan.engine
    core, core_spacing, core_normals = options.core, options.core_spacing, options.core_normals
    tile_size = options.tile_size  # chosen below from the memory limit when not given
    limit, threads, chunk_size, log = options.limit, options.threads, options.chunk_size, options.log
    read_points = options.read_points
    execute = _executor(client, options.retries, log, report)
    # memory plan: the fixed costs (what this process holds, the streaming and merge chunks)
    mem = None
    stream_rows = merge_rows = chunk_size
    if limit is not None:
        mem = plan_memory(limit, rss_bytes(), chunk_size)
        stream_rows = mem.stream_rows

    # 1. vegetation removed (--classifier / --keep): each cloud read through its keep mask
    if plan.filter is not None:
        t0 = time.perf_counter()
        size_c = tile_size
        if size_c is None:
            _, rho = density(ref_src, stream_rows)
            size_c = choose_tile_size(limit, plan.filter.reach, rho, 0.0, rho, base=mem.base)
        ref_src = classify_tiled(plan.filter, "reference", ref_src, spills, size_c, stream_rows, execute, threads)
        cmp_src = classify_tiled(plan.filter, "compared", cmp_src, spills, size_c, stream_rows, execute, threads)
        release_memory()
        report.seconds["classify"] = time.perf_counter() - t0

    # 2. core points
    normals_arr = None
    if values["normal_source"] == "core":
        if core_normals is None:
            raise UsageError("--normal-source core needs core_normals (one normal per core point)")
        normals_arr = as_points("core_normals", core_normals)
    if core is not None and core_spacing is not None:
        raise UsageError("give either core points (--core) or --core-spacing, not both")
    if core is not None:
        if isinstance(core, (str, os.PathLike)):
            from ..io import read_cloud
            core = read_cloud(core, drop_nonfinite=options.drop_nonfinite)
        core_arr = as_points("core_points", core)
        cores = CoreStream(array=core_arr, normals=normals_arr)
    elif core_spacing is not None:
        t0 = time.perf_counter()
        core_arr = streaming_subsample(ref_src, positive("--core-spacing", core_spacing), stream_rows)
        report.seconds["core_subsample"] = time.perf_counter() - t0
        cores = CoreStream(array=core_arr, normals=normals_arr)
    else:
        core_arr = None
        cores = CoreStream(source=ref_src, normals=None)
    if normals_arr is not None and (core_arr is None or len(normals_arr) != len(core_arr)):
        raise UsageError("core_normals must have one row per core point")
    if orientation.needs_core_points(values["orient"]):  # their barycentre, the same bits as in memory
        plan.engine = engine_p = engine_params(values, "compare", read_points,
                                               core_points=lambda: (xyz for xyz, _ in cores.chunks(stream_rows)))

    # Tiles are anchored at the core points' lowest x and y where that is known without a pass
    # (any anchor gives the same results): a tile as large as the survey is then one tile.
    extent = None  # the core points' XY extent, where known
    if core_arr is not None and len(core_arr):
        origin, top = bounds(core_arr[:, :2])
        extent = top - origin
    elif ref_src.kind in ("las", "copc"):
        import laspy
        with laspy.open(ref_src.path) as r:
            origin = np.asarray(r.header.mins, dtype=np.float64)[:2]
            extent = np.asarray(r.header.maxs, dtype=np.float64)[:2] - origin
    else:
        origin = None  # the first core point

    # tile size; the memory plan again, now that the core points are held
    if mem is not None:
        mem = plan_memory(limit, rss_bytes(), chunk_size)
        stream_rows, merge_rows = mem.stream_rows, mem.merge_rows
        report.memory_plan = mem
    if tile_size is None:
        n_ref, rho_ref = density(ref_src, stream_rows)
        _, rho_cmp = density(cmp_src, stream_rows)
        if core_arr is None:
            rho_core = rho_ref
        else:
            lo, hi = bounds(core_arr) if len(core_arr) else (np.zeros(3), np.ones(3))
            span = hi - lo
            rho_core = len(core_arr) / max(float(span[0] * span[1]), 1e-12)
        tile_size = choose_tile_size(limit, h, rho_ref, rho_cmp, rho_core, base=mem.base)
        per_axis = np.maximum(np.ceil(extent / tile_size), 1) if extent is not None else np.ones(2)
        if per_axis.max() >= 2:
            # As many tiles per axis, all of one size: the smallest side that needs no more
            # (at least half the chosen one); smaller tiles only lower the peak.
            tile_size = min(tile_size, float((extent / per_axis).max()) * (1 + 1e-9))
        log(f"--memory-limit {limit} B: tile size {tile_size:.6g}")
    if mem is not None:
        log(f"memory plan: base {mem.base / 2**20:.0f} MiB, streaming chunks of {mem.stream_rows} rows, "
            f"merge chunks of {mem.merge_rows} rows")
    size = float(tile_size)
    report.tile_size = size

    # 3. partition: tile of every core point, per-tile core spills and boxes; the clouds spilled
    # into every tile box that holds each point. Each phase runs in its own function, so that its
    # buffers are gone (and handed back to the system, release_memory) before the next phase's peak.
    t0 = time.perf_counter()
    tiles = plan_tiles(spills, cores, size, origin, stream_rows)
    report.core_points, report.tiles = tiles.n_core, len(tiles)
    if tiles.n_core == 0:
        raise UsageError("no core points")
    tiles.lo -= hp  # each tile's box: its core points' bounding box grown by the halo
    tiles.hi += hp
    release_memory()
    report.seconds["plan"] = time.perf_counter() - t0
    log(f"{tiles.n_core} core points in {len(tiles)} tiles of {size:.6g} (halo {hp:.6g})")

    t0 = time.perf_counter()
    moved = {"reference": None, "compared": None}
    if "transform" in shared and not shared.get("transform_applied"):  # EP: the engine moves the compared cloud
        moved["compared"] = lambda xyz: uncertainty_inputs.moved_compared(shared, xyz)
    streamed, n_points = {}, {}
    for name, src in (("reference", ref_src), ("compared", cmp_src)):
        streamed[name] = src.kind != "copc" or bool(plan.carried[name]) or moved[name] is not None
        if streamed[name]:
            n_points[name] = distribute(src, spills, name, tiles, hp, stream_rows, carried=plan.carried[name],
                                        moved=moved[name], name=name)
            release_memory()
    report.reference_points = n_points.get("reference", 0)
    report.compared_points = n_points.get("compared", 0)
    report.seconds["distribute"] = time.perf_counter() - t0
    tasks = _tasks(plan, tiles, spills, ref_src, cmp_src, streamed, shared, hp, normals_arr is not None)

    # 4. compute: per-tile results spilled to disk, each tile exactly once
    t0 = time.perf_counter()
    state = {"dtype": None, "done": set(), "tile_points_max": 0, "tile_points_total": 0}
    counts = tiles.counts

    def accept(out: dict) -> None:
        t = int(out["tile"])
        if t in state["done"]:
            raise M3C2Error(f"tile {t} returned twice")
        if out["n"] != counts[t]:
            raise M3C2Error(f"tile {t} returned {out['n']} rows for {counts[t]} core points")
        if state["dtype"] is None:
            state["dtype"] = result_dtype(out)
        spills.write("result", t, result_rows(out, state["dtype"]))
        state["done"].add(t)
        pts = int(out["n_reference"]) + int(out["n_compared"])
        state["tile_points_max"] = max(state["tile_points_max"], pts)
        state["tile_points_total"] += pts

    execute(tasks, options.task_fn, accept, (engine_p, threads))
    if len(state["done"]) != len(tiles):
        raise M3C2Error(f"only {len(state['done'])} of {len(tiles)} tiles were computed")
    report.tile_points_max = state["tile_points_max"]
    report.tile_points_total = state["tile_points_total"]
    base = report.memory_plan.base if report.memory_plan is not None else BASE_BYTES
    report.estimated_tile_bytes_max = int(base + BYTES_PER_POINT * report.tile_points_max
                                          + BYTES_PER_CORE * int(counts.max()))
    report.seconds["compute"] = time.perf_counter() - t0

    # 5. merge in core order and write
    release_memory()
    t0 = time.perf_counter()
    merge(spills, state["dtype"], counts, tiles.n_core, report, output=options.output, like=ref_src.like(),
          projected=options.projected, position=options.position, storage=options.storage,
          return_result=options.return_result, chunk_size=merge_rows, record=plan.record)
    report.seconds["merge_write"] = time.perf_counter() - t0
    report.warnings = diagnostics.warn(report.evidence, values)  # the same as an in-memory run's
    return report


def _tasks(plan: Plan, tiles: Tiles, spills: SpillFolder, ref_src, cmp_src, streamed: dict, shared: dict, hp: float,
           with_normals: bool) -> list[TileTask]:
    lo, hi = tiles.lo, tiles.hi
    columns = {name: [c.column for c in plan.carried[name]] for name in ("reference", "compared")}

    def cloud_input(name, src, t):
        if not streamed[name]:
            return CloudInput(copc=str(src.path), lo=tuple(lo[t]), hi=tuple(hi[t]), drop_nonfinite=src.drop_nonfinite)
        return CloudInput(spill=spills.path(name, t), columns=columns[name])

    far = hi.max(axis=0) + 4 * hp + 1.0
    far_cmp = uncertainty_inputs.unmoved_compared(shared, far[None, :])[0]
    tables = {"1": shared.get("scan_positions1"), "2": shared.get("scan_positions2")}
    fillers = {c.keyword: c.filler(tables[c.keyword[-1]]) for cs in plan.carried.values() for c in cs}
    return [TileTask(tile=t, n_core=int(tiles.counts[t]), core_path=spills.path("core", t),
                     normals_path=spills.path("normals", t) if with_normals else None,
                     reference=cloud_input("reference", ref_src, t), compared=cloud_input("compared", cmp_src, t),
                     far_point=tuple(float(v) for v in far), far_point_compared=tuple(float(v) for v in far_cmp),
                     shared=shared, fillers=fillers) for t in range(len(tiles))]
