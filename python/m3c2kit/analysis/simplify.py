"""Self-comparison: simplification by local averaging or outlier removal (section 6.3).

The cloud is compared with itself at the core points; the projection of each core point on the
cloud, core + i * n (i the mean of the cylinder's points along the normal, or their median with
--median), is the simplified point. Attached scalars: the roughness sigma(D) of the normal fit,
the spread sigma(d) along the normal in the cylinder, the density n (points in the cylinder of
diameter d and half-length max_depth) and n / (pi (d/2)^2) per unit area, and the normal.
"""
from __future__ import annotations

import math

import numpy as np

from ..run import in_memory
from ..run.checks import as_points
from ..base.errors import UsageError

COLUMNS = ("roughness", "sigma", "density", "density_per_area", "nx", "ny", "nz", "normal_scale", "offset", "status")


def simplify(cloud, core=None, *, projection_scale: float, normal_scale=None, core_spacing=None, median: bool = False,
             max_depth: float | None = None, vertical: bool = False, orient="+z", threads: int = 0,
             progress=None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """(points, fields): the projected positions (NaN rows dropped) and their scalars.
    normal_scale defaults to 2 d; max_depth to d; vertical imposes (0, 0, 1) normals."""
    pts = as_points("cloud", cloud)
    d = float(projection_scale)
    if not (math.isfinite(d) and d > 0):
        raise UsageError(f"--projection-scale must be finite and > 0, got {projection_scale!r}")
    params = dict(projection_scale=d, max_depth=float(max_depth) if max_depth is not None else d, median=median,
                  orient=orient, min_points=1, threads=threads, progress=progress, core_spacing=core_spacing)
    if vertical:
        if normal_scale is not None:  # refused, never ignored (docs/errors.md, issue 31 item 5)
            raise UsageError("--normal-scale would change nothing in this run: --vertical imposes vertical "
                             "normals; leave one of them out")
        params["normal_source"] = "vertical"
    elif normal_scale is not None:
        params["normal_scale"] = normal_scale
    elif math.isfinite(2 * d):
        params["normal_scale"] = 2 * d
    else:  # the default would name --normal-scale, which the user did not give
        raise UsageError(f"--projection-scale {projection_scale!r} is too large: the default --normal-scale "
                         f"2 d is not finite; give --normal-scale")
    result = in_memory.compare(pts, pts, core, **params)
    projected = result.projected(1)
    keep = np.isfinite(projected).all(axis=1)
    n = result.n1.astype(np.float64)
    fields = {
        "roughness": result.roughness, "sigma": result.sigma1, "density": n,
        "density_per_area": n / (math.pi * (d / 2) ** 2),
        "nx": result.normal[:, 0], "ny": result.normal[:, 1], "nz": result.normal[:, 2],
        "normal_scale": result.normal_scale, "offset": result.i1, "status": result.status.astype(np.uint8),
    }
    return projected[keep], {k: np.asarray(v)[keep] for k, v in fields.items()}
