"""Bounds on what a parameter sizes, checked before any work (issue 15, docs/errors.md "Run
limits"): lengths that are usable floats, and a tile size that is not so small beside the halo
that every point is read by thousands of tiles."""
from __future__ import annotations

import math
import sys

from ..base.errors import UsageError

__all__ = ["usable_length", "check_halo", "check_tile_size", "MIN_TILE_TO_HALO"]

#: A tile of side S reads its own area grown by the halo h on every side: (S + 2h)^2 / S^2 times
#: its area, about 25 times at S = h / 2 (S = 4 h, the usual choice, reads 2.25 times). Below it
#: the run reads each point thousands of times (Toronto with --max-depth 30 --tile-size 0.5 grew
#: without bound for minutes; untiled it takes 1 s).
MIN_TILE_TO_HALO = 0.5


def usable_length(option: str, value) -> float:
    """`value` as a length: a finite float > 0 that is a normal float (not below
    sys.float_info.min = 2.2e-308: 5e-324 divides everything into infinities), else a
    UsageError naming `option`."""
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
        raise UsageError(f"{option} must be a positive number, got {value!r}") from None
    if not math.isfinite(v) or v <= 0:
        raise UsageError(f"{option} must be a finite, positive length, got {value!r}")
    if v < sys.float_info.min:
        raise UsageError(f"{option} {value!r} is too small to be a length (below {sys.float_info.min:.3g}, "
                         f"the smallest normal float)")
    return v


def check_halo(halo: float) -> None:
    """A UsageError when the halo (the reach of the scales and --max-depth, summed) is no finite
    length: lengths near the float range's end sum to infinity, and a tile count or a tile's reach
    in tiles computed from it would overflow."""
    if not math.isfinite(4 * halo):  # 4 x the halo: the tile size the messages suggest, 2 x: a tile's reach
        raise UsageError("the halo of the tiles (the reach of the normal and projection scales and --max-depth) "
                         "exceeds the largest float; give lengths that fit the clouds' extent")


def check_tile_size(tile_size: float, halo: float) -> None:
    """A UsageError naming --tile-size and the halo when tiles are smaller than
    MIN_TILE_TO_HALO x the halo."""
    if tile_size < MIN_TILE_TO_HALO * halo:
        ratio = (tile_size + 2 * halo) / tile_size
        reads = ratio * ratio  # not ratio ** 2: a float power raises OverflowError past 1e308, a product is inf
        about = f"about {reads:.3g}" if math.isfinite(reads) else "more than 1e308"
        raise UsageError(f"--tile-size {tile_size:.6g} is too small for the halo of {halo:.6g} (the reach of the "
                         f"normal and projection scales and --max-depth): each tile would read {about} "
                         f"times its own area; use --tile-size {MIN_TILE_TO_HALO * halo:.6g} or more "
                         f"(4 x the halo, {4 * halo:.6g}, reads 2.25 times), or --memory-limit to choose it")
