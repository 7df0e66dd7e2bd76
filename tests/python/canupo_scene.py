"""Seeded synthetic scenes for the CANUPO tests: a rough ground surface with shrubs and trees as
3D scatter of several sizes (label 2 = ground, 3 = vegetation, the LAS codes)."""
from __future__ import annotations

import numpy as np

GROUND, VEGETATION = 2, 3


def ground_height(x, y, phases):
    """Rough terrain: three sinusoid pairs of 12, 4.5 and 1.3 m wavelength (0.6, 0.2, 0.05 m)."""
    z = np.zeros_like(x)
    for (amp, wl), (px, py) in zip(((0.6, 12.0), (0.2, 4.5), (0.05, 1.3)), phases):
        z += amp * np.sin(2 * np.pi * x / wl + px) * np.cos(2 * np.pi * y / wl + py)
    return z


def scene(seed: int, size: float = 30.0, density: float = 40.0, origin=(0.0, 0.0, 0.0)):
    """(xyz (N, 3), labels (N,)): ground at `density` points/m^2 with 2 cm noise, ~size^2/40
    shrubs (ellipsoids 0.3-0.8 m, points in their volume) and ~size^2/150 trees (a trunk of
    points on a 0.1-0.2 m cylinder and a 1-2.5 m crown), all of their points labelled vegetation."""
    rng = np.random.default_rng(seed)
    phases = rng.uniform(0, 2 * np.pi, (3, 2))
    n = int(density * size * size)
    gx, gy = rng.uniform(0, size, n), rng.uniform(0, size, n)
    ground = np.c_[gx, gy, ground_height(gx, gy, phases) + rng.normal(0, 0.02, n)]
    parts = [ground]
    for _ in range(int(size * size / 40)):  # shrubs
        c = rng.uniform(1, size - 1, 2)
        r = rng.uniform(0.3, 0.8, 3) * np.array([1, 1, 0.8])
        m = int(rng.uniform(300, 1200) * np.prod(r) / 0.1)
        u = rng.normal(size=(m, 3))
        u *= (rng.uniform(0, 1, m) ** (1 / 3) / np.linalg.norm(u, axis=1))[:, None]
        base = ground_height(c[:1], c[1:], phases)[0]
        parts.append(np.c_[c[0] + r[0] * u[:, 0], c[1] + r[1] * u[:, 1], base + r[2] * (1.0 + u[:, 2])])
    for _ in range(int(size * size / 150)):  # trees
        c = rng.uniform(3, size - 3, 2)
        base = ground_height(c[:1], c[1:], phases)[0]
        height, trunk_r, crown_r = rng.uniform(2, 4), rng.uniform(0.1, 0.2), rng.uniform(1.0, 2.5)
        m = int(400 * height)
        a, h = rng.uniform(0, 2 * np.pi, m), rng.uniform(0.1, height, m)
        parts.append(np.c_[c[0] + trunk_r * np.cos(a), c[1] + trunk_r * np.sin(a), base + h])
        m = int(600 * crown_r ** 3)
        u = rng.normal(size=(m, 3))
        u *= (rng.uniform(0, 1, m) ** (1 / 3) / np.linalg.norm(u, axis=1))[:, None]
        parts.append(np.c_[c[0] + crown_r * u[:, 0], c[1] + crown_r * u[:, 1], base + height + crown_r * (1 + u[:, 2])])
    xyz = np.vstack(parts) + np.asarray(origin, float)
    labels = np.full(len(xyz), VEGETATION, dtype=np.uint8)
    labels[:n] = GROUND
    return xyz, labels
