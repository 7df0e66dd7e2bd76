"""The CANUPO features of a cloud: the only module of m3c2kit.classify that calls the engine
(m3c2kit.engine.dimensionality)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import engine

SQRT3_2 = np.sqrt(3.0) / 2.0


@dataclass
class Features:
    """Per core point i and scale k (the order of `scales`).

    proportions[i, k]: eigenvalue shares p1 >= p2 >= p3 (sum 1); barycentric[i, k]: (a, b, c), the
    1D, 2D and 3D weights; triangle[i, k]: CANUPO's plane coordinates of the point of the triangle,
    (x, y) = (b + c / 2, c sqrt(3) / 2) (1D at (0, 0), 2D at (1, 0), 3D at (1/2, sqrt(3)/2));
    count[i, k]: neighbours; ok[i]: the features exist (status 0). NaN where not ok.
    """
    scales: np.ndarray
    proportions: np.ndarray
    barycentric: np.ndarray
    count: np.ndarray
    status: np.ndarray

    @property
    def ok(self) -> np.ndarray:
        return self.status == 0

    @property
    def triangle(self) -> np.ndarray:
        b, c = self.barycentric[..., 1], self.barycentric[..., 2]
        return np.stack([b + c / 2.0, c * SQRT3_2], axis=-1)

    def vector(self) -> np.ndarray:
        """(N, 2 S): x and y of each scale in turn, CANUPO's descriptor layout."""
        t = self.triangle
        return t.reshape(len(t), -1)


def features(cloud_xyz, scales, core_xyz=None, *, min_points: int = 3, threads: int = 0,
             progress=None) -> Features:
    """Dimensionality features of `cloud_xyz` at `core_xyz` (default: every point) for each scale
    (sphere diameters). A scale with fewer than `min_points` neighbours takes the next larger
    scale's values (CANUPO's rule); a point with too few at the largest scale has NaN."""
    cloud_xyz = np.ascontiguousarray(cloud_xyz, dtype=np.float64)
    core = cloud_xyz if core_xyz is None else np.ascontiguousarray(core_xyz, dtype=np.float64)
    scales = np.asarray(scales, dtype=np.float64).ravel()
    r = engine.dimensionality(cloud_xyz, core, scales, min_points, threads=threads, progress=progress)
    return Features(scales, r["proportions"], r["barycentric"], r["count"], r["status"])
