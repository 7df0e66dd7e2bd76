"""The core points of a run: given ones, the reference subsampled to a minimum spacing (in memory,
or streaming with the same result), or the reference itself."""
from __future__ import annotations

import numpy as np

from .. import engine
from ..base.errors import M3C2Error, UsageError
from ..io.arrays import bounds
from ..io.streaming import DEFAULT_CHUNK, PointSource, _in_box
from ..settings.parsers import positive
from .checks import as_points, check_spacing

def core_points_for(reference: np.ndarray, core_points=None, core_spacing=None) -> np.ndarray:
    """The core points: given ones, the reference subsampled to a minimum spacing, or the reference."""
    if core_points is not None and core_spacing is not None:
        raise UsageError("give either core points (--core) or --core-spacing, not both")
    if core_points is not None:
        return as_points("core_points", core_points)
    if core_spacing is not None:
        spacing = check_spacing("--core-spacing", positive("--core-spacing", core_spacing), reference)
        kept = engine.subsample_min_spacing(reference, spacing, "--core-spacing")
        return reference[kept]
    return reference


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
            lo, hi = bounds(xyz)
            mask = _in_box(kept, lo - margin, hi + margin)
            mask[0] = False
            near = np.concatenate([first, kept[mask]])
        pts = np.ascontiguousarray(np.concatenate([near, xyz]))
        idx = engine.subsample_min_spacing(pts, spacing, "--core-spacing")
        prefix = len(near)
        if prefix and (len(idx) < prefix or not np.array_equal(idx[:prefix], np.arange(prefix))):
            raise M3C2Error("internal error: streaming subsampling diverged from the global one")
        kept = np.concatenate([kept, pts[idx[idx >= prefix]]])
    return kept


