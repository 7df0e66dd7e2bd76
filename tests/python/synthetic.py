"""Seeded synthetic clouds shared by the Python tests."""
from __future__ import annotations

import numpy as np


def noisy_plane_pair(n: int = 120, spacing: float = 0.05, offset: float = 0.1, noise: float = 0.002, seed: int = 7):
    """Two horizontal planes on a jittered grid, the second `offset` higher (the true change)."""
    rng = np.random.default_rng(seed)
    g = np.stack(np.meshgrid(np.arange(n) * spacing, np.arange(n) * spacing), -1).reshape(-1, 2)
    ref = np.column_stack([g + rng.uniform(-spacing / 4, spacing / 4, g.shape), rng.normal(0, noise, len(g))])
    cmp = np.column_stack([g + rng.uniform(-spacing / 4, spacing / 4, g.shape), offset + rng.normal(0, noise, len(g))])
    return ref, cmp


def grid(n: int = 20, spacing: float = 0.1, z: float = 0.0) -> np.ndarray:
    """An exact n x n grid of points `spacing` apart at height `z` (no noise: planar clouds)."""
    g = np.stack(np.meshgrid(np.arange(n) * spacing, np.arange(n) * spacing), -1).reshape(-1, 2)
    return np.column_stack([g, np.full(len(g), z)])


def write_xyz(path, xyz, header: bool = False) -> None:
    with open(path, "w") as f:
        if header:
            f.write("x y z\n")
        for p in xyz:
            f.write(" ".join(repr(float(c)) for c in p) + "\n")
