"""What a tiled run is asked and checked before any file is read (docs/scaling.md,
docs/errors.md "Run limits"): :class:`TiledOptions`, how the run is cut and executed (never what
it computes), and :func:`prepare`, the plan made once (m3c2kit.run.plan, the in-memory run's
checks) with the checks of tiling itself: the options tiles cannot reproduce, the tile size
against the halo, the memory limit."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from .. import engine
from ..base.errors import UsageError
from ..io.streaming import DEFAULT_CHUNK
from ..settings.limits import check_halo, check_tile_size, usable_length
from .memory import parse_memory
from .plan import Plan, make_plan
from .tasks import compute_tile

__all__ = ["TiledOptions", "TiledPlan", "prepare"]


@dataclass(frozen=True)
class TiledOptions:
    """How a tiled run is cut and executed (never what it computes): the tile side `tile_size`, or
    `memory_limit` (bytes or '2GB': the side chosen so a tile's estimated resident memory fits);
    the tiles as Dask tasks on `client` (a distributed.Client) or on the scheduler at
    `dask_scheduler`, each retried `retries` times; the spill folder `work_dir` (default: a private
    one beside the output); rows read per streamed chunk (`chunk_size`); non-finite points of inputs
    given as paths dropped (`drop_nonfinite`, else an error); the task run per tile (`task_fn`, a
    testing aid) and `log`, told the run's progress."""

    tile_size: float | None = None
    memory_limit: int | str | None = None
    client: object = None
    dask_scheduler: str | None = None
    retries: int = 3
    work_dir: object = None
    chunk_size: int = DEFAULT_CHUNK
    drop_nonfinite: bool = False
    task_fn: Callable = compute_tile
    log: Callable[[str], object] = lambda s: None


@dataclass
class TiledPlan:
    """A tiled run's plan, made once and checked before any file is read (docs/errors.md, "Run
    limits"): the plan (m3c2kit.run.plan), the neighbourhood's reach h and the tile halo, the tile
    size (None: from the memory limit) and the memory limit in bytes."""

    plan: Plan
    reach: float
    halo: float
    tile_size: float | None
    limit: int | None
    read_points: Callable | None = None  # how the plan reads files of points (--orient FILE)

    def orient(self, spec) -> None:
        """--orient as resolved with the files' scanner positions (orientation.for_clouds), known
        once they are read: the plan's, as the in-memory run takes it (the engine's Params are made
        again with the core points, _core_points)."""
        self.plan.given["orient"] = spec
        self.plan.values["orient"] = spec


def prepare(params: dict, tiling: TiledOptions = TiledOptions(), *, vegetation=None, read_points=None) -> TiledPlan:
    """The plan of a tiled run of compare(**params) and its checks that need no file: the options
    tiles cannot reproduce (their results depend on the whole cloud's order or the core point's
    index in the run), the tile size against the halo, the memory limit."""
    plan = make_plan(params, read_points, vegetation=vegetation)
    values, engine_p = plan.values, plan.engine
    if engine_p.normal_subsample_spacing > 0:
        raise UsageError("--normal-subsample cannot be combined with tiling (--tile-size, --memory-limit, "
                         "--dask-scheduler): the subsampled normal cloud depends on the whole cloud's order, "
                         "so tiles would not reproduce the untiled result")
    if values["lod"] == "bootstrap":
        raise UsageError("--bootstrap cannot be combined with tiling: the bootstrap stream is seeded by the "
                         "core point's index in the run, which a tile does not know")
    tile_size, memory_limit = tiling.tile_size, tiling.memory_limit
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
    return TiledPlan(plan, h, engine.tile_halo(engine_p), tile_size, limit, read_points)
