"""A rough synthetic terrain (not a plane) sampled twice, the second epoch with a real change on
20 % of the area and moved by a known rigid motion (seeded, fixed)."""
from __future__ import annotations

import numpy as np

#: The motion that maps the compared epoch back onto the reference (its matrix is what
#: m3c2 register must find).
ROTATION_DEGREES = (0.3, -0.2, 0.5)
TRANSLATION = (0.08, -0.05, 0.04)
EXTENT = 20.0
CHANGED_FROM_X = 0.8 * EXTENT  # x > 16: a 0.3 m deposit on a fifth of the area


def height(x, y):
    return 0.8 * np.sin(0.7 * x) * np.cos(0.5 * y) + 0.3 * np.sin(1.1 * x + 0.9 * y)


def rotation(vector) -> np.ndarray:
    w = np.asarray(vector, dtype=float)
    a = np.linalg.norm(w)
    k = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / a
    return np.eye(3) + np.sin(a) * k + (1 - np.cos(a)) * k @ k


def true_matrix() -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = rotation(np.radians(ROTATION_DEGREES))
    m[:3, 3] = TRANSLATION
    return m


def epochs(n: int, seed: int, noise: float = 0.003, change: float = 0.3):
    """(reference, compared): n points each, xy uniform on [0, EXTENT]^2, z noise `noise`."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, EXTENT, (n, 2))
    reference = np.column_stack([xy, height(*xy.T) + rng.normal(0, noise, n)])
    xy = rng.uniform(0, EXTENT, (n, 2))
    z = height(*xy.T) + rng.normal(0, noise, n) + np.where(xy[:, 0] > CHANGED_FROM_X, change, 0.0)
    m = true_matrix()
    compared = (np.column_stack([xy, z]) - m[:3, 3]) @ m[:3, :3]  # R^T (p - t), row by row
    return np.ascontiguousarray(reference), np.ascontiguousarray(compared)


def errors(matrix: np.ndarray) -> tuple[float, float]:
    """(rotation error in degrees, translation error) of `matrix` against the true motion."""
    m = true_matrix()
    d = matrix[:3, :3] @ m[:3, :3].T
    angle = float(np.degrees(np.arccos(min(1.0, (np.trace(d) - 1) / 2))))
    return angle, float(np.linalg.norm(matrix[:3, 3] - m[:3, 3]))


STABLE_GEOJSON = {"type": "FeatureCollection", "features": [{"type": "Feature", "properties": {"name": "stable"},
                  "geometry": {"type": "Polygon", "coordinates": [[[-1, -1], [15, -1], [15, 21], [-1, 21], [-1, -1]]]}}]}
