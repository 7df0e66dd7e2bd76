"""Executing a plan in tiles (out of core), on this machine or as tasks on a Dask cluster. The
merged result is identical, bit for bit and in core-point order, to the in-memory run of the same
plan (docs/scaling.md gives the argument), and so is everything written from it: the point table
with the core points' own attributes, the --grid rasters and the report (m3c2kit.output), and the
data-quality warnings.

Steps (:func:`run_tiled`), each bounded in memory, each a function of the run's state (:class:`_Run`):

0. :func:`prepare`, before any file is read: the plan (m3c2kit.run.plan, the in-memory run's
   checks), the options tiles cannot reproduce, the tile size against the halo, the memory limit;
   then the Dask scheduler reached (bounded in time, m3c2kit.run.dask).
1. :func:`_filter`: with --classifier, each cloud classified tile by tile, then read through its
   keep mask (m3c2kit.run.vegetation).
2. :func:`_core_points`: every reference point (streamed), the reference subsampled with
   ``core_spacing`` (once, globally, streaming, :func:`m3c2kit.run.cores.streaming_subsample`),
   a --grid over the reference (streaming, m3c2kit.run.grid_cores), or given ones.
3. :func:`_tile_size` and :func:`_partition` (m3c2kit.run.partition): the tile of every core
   point, per-tile core spills; each cloud streamed once into every tile box (core points' box +
   halo) that holds its points, with the per-point inputs it carries (--uncertainty pm precisions,
   ep scan-position ids). A COPC input is read per tile with a box query instead when it carries
   nothing.
4. :func:`_compute`: tile by tile, or as Dask tasks (m3c2kit.run.dask.execute), each task reading
   its inputs from paths and making the in-memory run's engine call (m3c2kit.run.tasks); results
   spilled to disk.
5. :func:`_merge` (m3c2kit.run.merge) in core order, written atomically with the in-memory writer's
   columns and the core points' attributes (m3c2kit.run.attributes); the warnings
   (m3c2kit.run.diagnostics, the empty-cylinder diagnosis reading the clouds by streaming:
   m3c2kit.run.cylinder_points) before the output is closed, as in memory before it is written.

Every spill write goes through m3c2kit.run.spill.SpillFolder (a failed write is one clean error);
the spill folder is removed whatever happens.
"""
from __future__ import annotations

import os
import tempfile
import time
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import dask as dask_run
from . import diagnostics, registration_inputs, uncertainty_inputs
from ..base.errors import M3C2Error, UsageError
from ..base.fault_hook import checkpoint as fault_checkpoint
from ..io.arrays import bounds
from ..io.atomic import private_folder
from ..io.fields import TableStyle
from ..io.streaming import DEFAULT_CHUNK, PointSource
from ..settings import engine_params, orientation
from ..settings.parsers import positive
from .attributes import core_attributes
from .checks import as_points, check_all_fields, check_core_normals
from .cores import streaming_subsample
from .cylinder_points import StreamedCloud
from .grid_cores import GridCores, streamed_grid
from .memory import (BASE_BYTES, BYTES_PER_CORE, BYTES_PER_POINT, MemoryPlan, choose_tile_size, density,
    plan_memory, release_memory, rss_bytes)
from .fdr import Fdr
from .fdr import check_memory as check_fdr_memory
from .merge import MergeTarget, ResultSpills, merge
from .outcome import TiledReport
from .partition import CoreStream, Tiles, distribute, plan_tiles
from .plan import Plan
from .spill import SpillFolder
from .tasks import CloudInput, TileTask, result_dtype, result_rows
from .tiled_plan import TiledOptions, TiledPlan, prepare
from .vegetation import classify_tiled

__all__ = ["TiledOptions", "TiledPlan", "GridCores", "prepare", "run_tiled"]


def run_tiled(reference, compared, core=None, *, core_normals=None, output=None, style: TableStyle = TableStyle(),
              tiling: TiledOptions = TiledOptions(), return_result: bool = False, prepared: TiledPlan | None = None,
              vegetation=None, read_points=None, **params) -> TiledReport:
    """Tiled M3C2 between the files `reference` and `compared` (paths, or PointSource).

    `core`: None (every reference point, or with ``core_spacing`` the reference subsampled), a core
    file path, an (N, 3) array or a Cloud, or GridCores(cell) (2D mode's grid over the reference,
    m3c2kit.run.raster); `core_normals` with ``normal_source="core"``. `output`: a file written
    atomically in `style` (m3c2kit.io.fields.TableStyle: the bytes of m3c2kit.write on the
    in-memory run's Result, the core points' attributes included). `return_result` also gathers the
    Result in memory (with the attributes and the grid: what the rasters and the report need).
    `tiling`: how the run is cut and executed (:class:`TiledOptions`). The other keywords are
    :func:`m3c2kit.compare`'s parameters, every one of them in every mode, with `vegetation` and
    `read_points` as m3c2kit.run.plan.make_plan takes them; or `prepared`, the plan
    :func:`prepare` made of them.
    """
    t_start = time.perf_counter()
    if prepared is None:
        prepared = prepare(params, tiling, vegetation=vegetation, read_points=read_points)
    elif params or vegetation is not None or read_points is not None:
        raise UsageError("give run_tiled the parameters, or the plan prepare() made of them, not both")
    check_core_normals(prepared.plan.values, core_normals)
    if output is not None or not return_result:  # a gathered Result may be written later (its caller checks)
        check_all_fields(output, style.all_fields)
    report = TiledReport(halo=prepared.reach, memory_limit=prepared.limit)
    client = tiling.client
    own_client = client is None and tiling.dask_scheduler is not None
    if own_client:
        client = dask_run.connect(tiling.dask_scheduler)  # bounded in time, before any file is read
    try:
        drop = tiling.drop_nonfinite
        ref_src = reference if not isinstance(reference, (str, os.PathLike)) else PointSource(reference,
                                                                                             drop_nonfinite=drop)
        cmp_src = compared if not isinstance(compared, (str, os.PathLike)) else PointSource(compared,
                                                                                           drop_nonfinite=drop)
        with ExitStack() as held:
            spills = _spill_folder(held, tiling.work_dir, output, client)
            run = _Run(prepared, tiling, report, spills, client, (ref_src, cmp_src))
            _filter(run)
            _core_points(run, core, core_normals)
            _tile_size(run)
            tasks = _partition(run)
            report.fdr = Fdr.of(run.values)
            report.confidence = float(run.values["confidence"])
            if report.fdr is not None and run.memory is not None:  # its global ranking, before any work
                check_fdr_memory(run.tiles.n_core, run.prepared.limit, run.memory.base + run.memory.merge_bytes)
            results = _compute(run, tasks)
            _merge(run, results, MergeTarget(output, ref_src.like(), style, run.attributes(style, output, return_result),
                                             return_result))
            report.seconds["total"] = time.perf_counter() - t_start
            return report
    finally:
        if own_client:
            client.close()


def _spill_folder(held: ExitStack, work_dir, output, client) -> SpillFolder:
    """The run's spill folder: a private one beside the output (or in the temporary folder),
    removed whatever happens, or `work_dir`."""
    if work_dir is not None:
        Path(work_dir).mkdir(parents=True, exist_ok=True)
        return SpillFolder(Path(work_dir))
    parent = Path(output).resolve().parent if output is not None else Path(tempfile.gettempdir())
    work = held.enter_context(private_folder(parent))
    fault_checkpoint("staging")  # a testing aid (docs/errors.md, "Interruption"): spill folder made
    # Dask workers (other processes) reach the folder only by its name; this process writes
    # through the pinned path whatever happens (run/spill.py).
    return SpillFolder(work.path, work.directory, work.directory / work.name if client is not None else None)


@dataclass
class _Run:
    """A tiled run's state, passed from step to step."""

    prepared: TiledPlan
    tiling: TiledOptions
    report: TiledReport
    spills: SpillFolder
    client: object
    given: tuple  # (reference, compared) sources as given: what the attributes and the warnings read
    sources: tuple = ()  # (reference, compared) as the comparison reads them (through a keep mask)
    memory: MemoryPlan | None = None
    stream_rows: int = DEFAULT_CHUNK
    merge_rows: int = DEFAULT_CHUNK
    cores: CoreStream | None = None
    core_array: np.ndarray | None = None  # the core points, when held in memory
    normals: np.ndarray | None = None     # the given core normals
    tile_size: float | None = None
    tiles: Tiles | None = None
    streamed: dict = field(default_factory=dict)  # cloud name -> spilled (else COPC box queries)
    shared: dict = field(default_factory=dict)    # EP's inputs every tile receives

    def __post_init__(self):
        self.sources = self.sources or self.given
        self.tile_size = self.prepared.tile_size
        self.shared = uncertainty_inputs.shared_inputs(self.values, self.given[0].like(), self.given[1].like())
        self.stream_rows = self.merge_rows = self.tiling.chunk_size
        if self.prepared.limit is not None:  # the fixed costs: what this process holds, the chunks
            self.memory = plan_memory(self.prepared.limit, rss_bytes(), self.tiling.chunk_size)
            self.stream_rows = self.memory.stream_rows

    @property
    def plan(self) -> Plan:
        return self.prepared.plan

    @property
    def values(self) -> dict:
        return self.plan.values

    def execute(self, tasks, fn, accept, args=()) -> None:
        """Every task once, on this machine or on the Dask client (m3c2kit.run.dask.execute)."""
        workers = dask_run.execute(tasks, fn, accept, client=self.client, retries=self.tiling.retries,
                                   log=self.tiling.log, args=args)
        if self.client is not None:
            self.report.dask, self.report.workers = True, workers

    def attributes(self, style: TableStyle, output, gather: bool):
        """The core points' attributes the outputs carry (m3c2kit.run.attributes), or None."""
        if not style.attributes or (output is None and not gather):
            return None
        if self.core_array is not None:  # matched in one pass, as the other streaming passes
            return core_attributes(self.given[0], self.core_array, self.stream_rows)
        # Read beside the merge, a merge chunk at a time: one chunk of each alive at once.
        return core_attributes(self.given[0], self.cores.source, self.merge_rows)


def _filter(run: _Run) -> None:
    """1. --classifier / --keep: each cloud classified tile by tile, then read through its keep mask."""
    filt = run.plan.filter
    if filt is None:
        return
    t0 = time.perf_counter()
    size = run.tile_size
    if size is None:
        _, rho = density(run.given[0], run.stream_rows)
        size = choose_tile_size(run.prepared.limit, filt.reach, rho, 0.0, rho, base=run.memory.base)
    threads = run.values["threads"]
    run.sources = tuple(classify_tiled(filt, name, src, run.spills, size, run.stream_rows, run.execute, threads)
                        for name, src in zip(("reference", "compared"), run.given))
    release_memory()
    run.report.seconds["classify"] = time.perf_counter() - t0


def _core_points(run: _Run, core, core_normals) -> None:
    """2. The core points: given, subsampled (streaming), a grid over the reference, or every
    reference point; the engine's Params made again now that the orientation's inputs are known
    (--orient barycentre reads the core points, the default and sensor the files' scanner
    positions), as the in-memory run makes them."""
    values, ref_src = run.values, run.sources[0]
    if values["normal_source"] == "core":
        if core_normals is None:
            raise UsageError("--normal-source core needs core_normals (one normal per core point)")
        run.normals = as_points("core_normals", core_normals)
    spacing = values["core_spacing"]
    if core is not None and spacing is not None:
        raise UsageError("give either core points (--core) or --core-spacing, not both")
    if isinstance(core, (str, os.PathLike)):
        from ..io import read_cloud
        core = read_cloud(core, drop_nonfinite=run.tiling.drop_nonfinite)
    sensor = orientation.scan_positions_of(run.given[0].cloud, core)
    if isinstance(core, GridCores):  # 2D mode: the grid over the reference as given (raster.grid_core_points)
        t0 = time.perf_counter()
        run.report.grid = streamed_grid(run.given[0], core.cell, run.spills, run.stream_rows)
        run.core_array = run.report.grid.core_points
        run.report.seconds["grid"] = time.perf_counter() - t0
    elif core is not None:
        run.core_array = as_points("core_points", core)
    elif spacing is not None:
        t0 = time.perf_counter()
        run.core_array = streaming_subsample(ref_src, positive("--core-spacing", spacing), run.stream_rows)
        run.report.seconds["core_subsample"] = time.perf_counter() - t0
    if run.core_array is not None:
        run.cores = CoreStream(array=run.core_array, normals=run.normals)
    else:
        run.cores = CoreStream(source=ref_src, normals=None)
    if run.normals is not None and (run.core_array is None or len(run.normals) != len(run.core_array)):
        raise UsageError("core_normals must have one row per core point")
    barycentre = orientation.needs_core_points(values["orient"])
    run.plan.engine = engine_params(values, "compare", run.prepared.read_points, scan_positions=sensor,
                                    core_points=(lambda: (xyz for xyz, _ in run.cores.chunks(run.stream_rows)))
                                    if barycentre else orientation.LATER)


def _anchor(run: _Run) -> tuple[np.ndarray | None, np.ndarray | None]:
    """(origin, extent) of the core points' XY where known without a pass: tiles are anchored at
    their lowest x and y (any anchor gives the same results), so that a tile as large as the
    survey is one tile; (None, None): the first core point anchors them."""
    ref_src = run.sources[0]
    if run.core_array is not None and len(run.core_array):
        origin, top = bounds(run.core_array[:, :2])
        return origin, top - origin
    if ref_src.kind in ("las", "copc"):
        import laspy
        with laspy.open(ref_src.path) as r:
            origin = np.asarray(r.header.mins, dtype=np.float64)[:2]
            return origin, np.asarray(r.header.maxs, dtype=np.float64)[:2] - origin
    return None, None


def _tile_size(run: _Run) -> None:
    """3a. The tile size (from the memory limit when not given), the memory plan made again now
    that the core points are held."""
    limit, log = run.prepared.limit, run.tiling.log
    if run.memory is not None:
        run.memory = plan_memory(limit, rss_bytes(), run.tiling.chunk_size)
        run.stream_rows, run.merge_rows = run.memory.stream_rows, run.memory.merge_rows
        run.report.memory_plan = run.memory
    if run.tile_size is None:
        ref_src, cmp_src = run.sources
        _, rho_ref = density(ref_src, run.stream_rows)
        _, rho_cmp = density(cmp_src, run.stream_rows)
        core_arr = run.core_array
        if core_arr is None:
            rho_core = rho_ref
        else:
            lo, hi = bounds(core_arr) if len(core_arr) else (np.zeros(3), np.ones(3))
            span = hi - lo
            rho_core = len(core_arr) / max(float(span[0] * span[1]), 1e-12)
        size = choose_tile_size(limit, run.prepared.reach, rho_ref, rho_cmp, rho_core, base=run.memory.base)
        _, extent = _anchor(run)
        per_axis = np.maximum(np.ceil(extent / size), 1) if extent is not None else np.ones(2)
        if per_axis.max() >= 2:
            # As many tiles per axis, all of one size: the smallest side that needs no more
            # (at least half the chosen one); smaller tiles only lower the peak.
            size = min(size, float((extent / per_axis).max()) * (1 + 1e-9))
        run.tile_size = size
        log(f"--memory-limit {limit} B: tile size {size:.6g}")
    if run.memory is not None:
        m = run.memory
        log(f"memory plan: base {m.base / 2**20:.0f} MiB, streaming chunks of {m.stream_rows} rows, "
            f"merge chunks of {m.merge_rows} rows")
    run.report.tile_size = float(run.tile_size)


def _partition(run: _Run) -> list[TileTask]:
    """3b. The tile of every core point, per-tile core spills and boxes; the clouds spilled into
    every tile box that holds each point. Each phase runs in its own function, so that its buffers
    are gone (and handed back to the system, release_memory) before the next phase's peak."""
    report, hp, size, rows = run.report, run.prepared.halo, float(run.tile_size), run.stream_rows
    t0 = time.perf_counter()
    origin, _ = _anchor(run)
    tiles = plan_tiles(run.spills, run.cores, size, origin, rows)
    report.core_points, report.tiles = tiles.n_core, len(tiles)
    if tiles.n_core == 0:
        raise UsageError("no core points")
    tiles.lo -= hp  # each tile's box: its core points' bounding box grown by the halo
    tiles.hi += hp
    run.tiles = tiles
    release_memory()
    report.seconds["plan"] = time.perf_counter() - t0
    run.tiling.log(f"{tiles.n_core} core points in {len(tiles)} tiles of {size:.6g} (halo {hp:.6g})")

    t0 = time.perf_counter()
    shared = run.shared
    moved = {"reference": None, "compared": None}
    if "transform" in shared and not shared.get("transform_applied"):  # EP: the engine moves the compared cloud
        moved["compared"] = lambda xyz: uncertainty_inputs.moved_compared(shared, xyz)
    counted = {}
    sources = list(run.sources)
    if registration_inputs.moves_compared(run.values):  # --transform T.json: moved as read, as in memory
        sources[1] = registration_inputs.MovedSource(sources[1], run.values)
    for name, src, given in zip(("reference", "compared"), sources, run.given):
        mover = isinstance(src, registration_inputs.MovedSource)
        run.streamed[name] = src.kind != "copc" or bool(run.plan.carried[name]) or moved[name] is not None or mover
        if run.streamed[name]:
            n = distribute(src, run.spills, name, tiles, hp, rows, carried=run.plan.carried[name],
                           moved=moved[name], name=name)
            if (src.source if mover else src) is given:  # the points read from the file (--classifier: those kept)
                counted[name] = n
            release_memory()
    report.reference_points = counted.get("reference", 0)
    report.compared_points = counted.get("compared", 0)
    report.seconds["distribute"] = time.perf_counter() - t0
    return _tasks(run.plan, tiles, run.spills, run.sources, run.streamed, shared, hp, run.normals is not None)


@dataclass
class _Computed:
    """What the tiles returned so far: the result rows' type, the tiles done, their cloud points."""

    dtype: np.dtype | None = None
    done: set = field(default_factory=set)
    tile_points_max: int = 0
    tile_points_total: int = 0


def _compute(run: _Run, tasks: list[TileTask]) -> ResultSpills:
    """4. Every tile computed exactly once, its result rows spilled to disk."""
    report, counts = run.report, run.tiles.counts
    t0 = time.perf_counter()
    state = _Computed()

    def accept(out: dict) -> None:
        t = int(out["tile"])
        if t in state.done:
            raise M3C2Error(f"tile {t} returned twice")
        if out["n"] != counts[t]:
            raise M3C2Error(f"tile {t} returned {out['n']} rows for {counts[t]} core points")
        if state.dtype is None:
            state.dtype = result_dtype(out)
        run.spills.write("result", t, result_rows(out, state.dtype))
        state.done.add(t)
        pts = int(out["n_reference"]) + int(out["n_compared"])
        state.tile_points_max = max(state.tile_points_max, pts)
        state.tile_points_total += pts

    run.execute(tasks, run.tiling.task_fn, accept, (run.plan.engine, run.values["threads"]))
    if len(state.done) != len(run.tiles):
        raise M3C2Error(f"only {len(state.done)} of {len(run.tiles)} tiles were computed")
    report.tile_points_max, report.tile_points_total = state.tile_points_max, state.tile_points_total
    base = report.memory_plan.base if report.memory_plan is not None else BASE_BYTES
    report.estimated_tile_bytes_max = int(base + BYTES_PER_POINT * report.tile_points_max
                                          + BYTES_PER_CORE * int(counts.max()))
    report.seconds["compute"] = time.perf_counter() - t0
    return ResultSpills(run.spills, state.dtype, counts, run.tiles.n_core, run.plan.record)


def _merge(run: _Run, results: ResultSpills, target: MergeTarget) -> None:
    """5. The rows merged in core order into the output; the run's warnings (those of an
    in-memory run: m3c2kit.run.diagnostics, the empty cylinders diagnosed on the clouds as given,
    streamed) before the output is closed."""
    release_memory()
    report = run.report
    t0 = time.perf_counter()
    clouds = tuple(StreamedCloud(src, run.stream_rows) for src in run.given)

    def warn(evidence) -> None:
        # Named at run_tiled's caller: warn <- this <- merge's finish <- merge <- _merge <- run_tiled.
        report.warnings = diagnostics.warn(evidence, run.values, *clouds, stacklevel=7)

    merge(results, target, report, run.merge_rows, warn, fdr=report.fdr)
    if target.gather and not report.reference_points:  # the report names the reference's size
        report.reference_points = sum(len(xyz) for xyz in run.given[0].chunks(run.stream_rows))
    report.seconds["merge_write"] = time.perf_counter() - t0


def _tasks(plan: Plan, tiles: Tiles, spills: SpillFolder, sources: tuple, streamed: dict, shared: dict, hp: float,
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
    ref_src, cmp_src = sources
    return [TileTask(tile=t, n_core=int(tiles.counts[t]), core_path=spills.path("core", t),
                     normals_path=spills.path("normals", t) if with_normals else None,
                     reference=cloud_input("reference", ref_src, t), compared=cloud_input("compared", cmp_src, t),
                     far_point=tuple(float(v) for v in far), far_point_compared=tuple(float(v) for v in far_cmp),
                     shared=shared, fillers=fillers) for t in range(len(tiles))]
