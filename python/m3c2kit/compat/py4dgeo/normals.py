"""py4dgeo's normals (its compute_multiscale_directions): m3c2kit's fitted normals at the given
radii (diameters 2r; several radii: py4dgeo's scale rule among those with a 3-point plane), each
turned towards py4dgeo's orientation vector (n . o >= 0). Used by M3C2.directions and
Epoch.calculate_normals."""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ...base.errors import UsageError
from ...run.in_memory import normals as fit_normals
from . import util

__all__ = ["oriented_normals", "direction"]


def direction(vector, where: str = "M3C2") -> np.ndarray:
    """py4dgeo's orientation vector, checked: any finite non-zero 3-vector."""
    v = np.asarray(vector, dtype=np.float64).ravel()
    if v.shape != (3,) or not np.isfinite(v).all() or not np.linalg.norm(v) > 0:
        raise UsageError(f"{where}: orientation_vector must be a finite non-zero 3-vector, got {vector!r}")
    return v


def oriented_normals(cloud: np.ndarray, core: np.ndarray, radii: Sequence[float],
                     orientation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(normals (N, 3), chosen radius (N,)) at `core` from `cloud`; NaN where no plane could be fitted."""
    scales = [2.0 * float(r) for r in radii]
    # Several scales: py4dgeo's rule (the largest (l2 - l3) / l1) among the scales with a plane
    # (3 points), as py4dgeo; m3c2kit's own default is the paper's most planar scale.
    extra = {"min_points_multiscale": 3, "scale_selection": "py4dgeo"} if len(scales) > 1 else {}
    out = fit_normals(cloud, core, normal_scale=scales if len(scales) > 1 else scales[0], orient="+z",
                      threads=util.get_num_threads(), **extra)
    normals = out["normal"]
    with np.errstate(invalid="ignore"):
        normals[normals @ orientation < 0] *= -1.0  # towards the orientation vector, as py4dgeo's
    return normals, out["normal_scale"] / 2.0
