"""Memory planning of a run (docs/scaling.md "Memory"): what one tile, one streaming chunk and one
merge chunk hold, the tile size a memory limit allows, and the in-memory run's own estimate (the
engine's index memory per point, engine.INDEX_MEMORY)."""
from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from .. import engine
from ..base import portable
from ..base.errors import M3C2Error, UsageError
from ..io.arrays import bounds
from ..io.guard import available_memory, format_bytes
from ..io.streaming import DEFAULT_CHUNK, PointSource

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
        side = s + 2 * h
        return a * side * side + b * s * s  # products reach inf where a float power raises OverflowError

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


def release_memory() -> None:
    """Hands the allocator's free pages back to the system between phases (glibc), so that one
    phase's freed buffers do not stay resident under the next phase's peak."""
    trim = portable.malloc_trim()
    if trim is not None:
        trim(0)


# --------------------------------------------------------------------------- core points


def rss_bytes() -> int:
    """This process's resident size (VmRSS), 0 where /proc is not there (base/portable.py)."""
    return portable.resident_bytes()


def density(source: PointSource, chunk_size: int) -> tuple[int, float]:
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
            chunk_lo, chunk_hi = bounds(xyz)
            lo, hi = np.minimum(lo, chunk_lo), np.maximum(hi, chunk_hi)
    area = max(float((hi[0] - lo[0]) * (hi[1] - lo[1])), 1e-12) if n else 1.0
    return n, n / area


# ------------------------------------------------------------------------------ in memory

class InsufficientMemory(M3C2Error):
    """A run would need more memory than is available (exit status 1)."""


def estimate_memory(n_reference: int, n_compared: int, n_core: int, params: engine.Params | None = None,
                    reorder_inputs: bool = False) -> int:
    """Bytes an in-memory compare run allocates beyond its inputs (an upper estimate,
    engine.memory_estimate): `params`, the engine's parameters (default ones when None), say
    which clouds' normals, and so node moments, are computed; `reorder_inputs`, whether the
    engine may order the clouds in place instead of copying them (m3c2kit.compare)."""
    return engine.memory_estimate(n_reference, n_compared, n_core, engine.Params() if params is None else params,
                                  reorder_inputs)


def check_memory(n_reference: int, n_compared: int, n_core: int, available: int | None = None,
                 params: engine.Params | None = None, reorder_inputs: bool = False) -> int:
    """Raises InsufficientMemory when estimate_memory(...) exceeds `available` bytes (default:
    m3c2kit.io.guard.available_memory(), which honours $M3C2_AVAILABLE_MEMORY); returns the estimate."""
    needed = estimate_memory(n_reference, n_compared, n_core, params, reorder_inputs)
    available = available_memory() if available is None else available
    if available is not None and needed > available:
        raise InsufficientMemory(
            f"not enough memory: this run needs about {format_bytes(needed)} (spatial index of "
            f"{n_reference} + {n_compared} points, results for {n_core} core points) but only "
            f"{format_bytes(available)} is available; process the clouds in tiles (--tile-size S or "
            f"--memory-limit SIZE), or use fewer core points (--core-spacing, or a smaller --core file)")
    return needed
