"""Out-of-core M3C2, kept for its users: the executor is m3c2kit.run (run_tiled in
m3c2kit.run.tiled; memory planning in m3c2kit.run.memory; docs/scaling.md)."""
from __future__ import annotations

from .run.cores import streaming_subsample
from .run.memory import (BASE_BYTES, BYTES_PER_CORE, BYTES_PER_POINT, CHUNK_SHARE, HEADROOM_BYTES, MERGE_BYTES_PER_ROW,
                         MIN_CHUNK, STREAM_BYTES_PER_ROW, MemoryPlan, choose_tile_size, parse_memory, plan_memory)
from .run.memory import rss_bytes as _rss_bytes
from .run.outcome import TiledReport
from .run.tasks import CloudInput, TileTask, compute_tile
from .run.tiled import run_tiled
from . import engine


def halo(params) -> float:
    """Largest distance from a core point to a point that can change its result (the engine's)."""
    return engine.neighbourhood_reach(params)


__all__ = ["halo", "run_tiled", "streaming_subsample", "parse_memory", "choose_tile_size", "plan_memory",
           "MemoryPlan", "compute_tile", "TileTask", "CloudInput", "TiledReport", "BYTES_PER_POINT", "BYTES_PER_CORE",
           "BASE_BYTES", "HEADROOM_BYTES", "STREAM_BYTES_PER_ROW", "MERGE_BYTES_PER_ROW", "MIN_CHUNK", "CHUNK_SHARE"]
