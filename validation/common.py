"""Shared pieces of the validation scripts: data loading, the peer runs and py4dgeo's defect rule.

Nothing here is part of the m3c2 package; py4dgeo is imported lazily, only by the functions that
run it, so the rule and the surface generators can be used without it.
"""
from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

import m3c2kit

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared" / "data" / "pairs"
#: The autzen pair and its peers' outputs travel with the repository (tests/data/pairs/autzen-bmx,
#: PROVENANCE.md there), so the agreement tests run from a clone.
AUTZEN = REPO / "tests" / "data" / "pairs" / "autzen-bmx"
TORONTO = SHARED / "toronto-ttp"
#: The Toronto pair bundled as LAZ (data/toronto-ttp): the same coordinates as TORONTO's text
#: files once printed back to their two decimals (bundled_toronto_xyz).
BUNDLED_TORONTO = REPO / "data" / "toronto-ttp"

#: m3c2's z at 95 % (exact quantile) and py4dgeo's rounded constant: our LOD is rescaled by
#: PY4DGEO_Z / Z95 before it is compared with py4dgeo's.
Z95 = 1.959963984540054
PY4DGEO_Z = 1.96

#: Autzen parameters (CloudCompare's run: NormalScale, SearchScale, SearchDepth).
AUTZEN_D, AUTZEN_d, AUTZEN_L = 2.780864, 5.780864, 5.5


# ----------------------------------------------------------------------------------------------
# Data
def load_autzen():
    ref = m3c2kit.read(AUTZEN / "autzen-bmx-2010.las").xyz
    cmp = m3c2kit.read(AUTZEN / "autzen-bmx-2023.las").xyz
    core = m3c2kit.read(AUTZEN / "autzen-bmx-largersample.txt").xyz
    cc = np.genfromtxt(AUTZEN / "autzen-bmx-cc.txt", delimiter=",", names=True)
    pdal = np.genfromtxt(AUTZEN / "autzen-bmx-m3c2.txt", delimiter=",", names=True)
    return ref, cmp, core, cc, pdal


def load_toronto():
    """TTP_15 (reference) and TTP_23 (compared): X Y Z columns, header line starting with //;
    from the bundled LAZ copies when the shared text files are absent (the same doubles)."""
    return tuple(toronto_xyz(name) for name in ("TTP_15.xyz", "TTP_23.xyz"))


def toronto_xyz(name: str) -> np.ndarray:
    """The X Y Z columns of shared TORONTO/name, or the same doubles from the bundled LAZ."""
    if (TORONTO / name).is_file():
        return np.ascontiguousarray(np.loadtxt(TORONTO / name, comments="//", usecols=(0, 1, 2)))
    return bundled_toronto_xyz(BUNDLED_TORONTO / name.replace(".xyz", ".laz"))


def bundled_toronto_xyz(path: Path) -> np.ndarray:
    """LAS stores the text's two decimals as integers times 0.01, whose products are not always
    the double nearest the decimal the text parser gives: printing to two decimals and parsing
    back yields the text's doubles exactly (the goldens' input hashes check it)."""
    xyz = m3c2kit.read(path).xyz
    return np.ascontiguousarray(np.char.mod("%.2f", xyz).astype(np.float64))


def sha256(*arrays) -> str:
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(str(a.dtype).encode() + str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


# ----------------------------------------------------------------------------------------------
# Synthetic self-affine rough surfaces (only +, -, *, / on seeded draws: the same bits everywhere)
def self_affine_grid(rng: np.random.Generator, levels: int, hurst: float, sigma: float) -> np.ndarray:
    """A (2**levels + 1)^2 self-affine height grid by random midpoint displacement.

    Starts from 2 x 2 Gaussian heights of standard deviation `sigma`; each refinement halves the
    spacing, places the new nodes at the mean of their neighbours and displaces them by a
    Gaussian of standard deviation sigma * 2**(-hurst * level) (Hurst exponent `hurst`).
    """
    z = rng.normal(0.0, sigma, (2, 2))
    for level in range(1, levels + 1):
        m = z.shape[0]
        z2 = np.empty((2 * m - 1, 2 * m - 1))
        z2[::2, ::2] = z
        z2[1::2, ::2] = (z[:-1, :] + z[1:, :]) / 2
        z2[::2, 1::2] = (z[:, :-1] + z[:, 1:]) / 2
        z2[1::2, 1::2] = (z[:-1, :-1] + z[1:, :-1] + z[:-1, 1:] + z[1:, 1:]) / 4
        new = np.ones(z2.shape, bool)
        new[::2, ::2] = False
        z2[new] += rng.normal(0.0, sigma * 2.0 ** (-hurst * level), int(new.sum()))
        z = z2
    return z


def bilinear(grid: np.ndarray, size: float, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Height of `grid` (spanning [0, size]^2) at (x, y) by bilinear interpolation."""
    m = grid.shape[0] - 1
    u, v = x / size * m, y / size * m
    i = np.minimum(np.floor(u).astype(np.int64), m - 1)
    j = np.minimum(np.floor(v).astype(np.int64), m - 1)
    fu, fv = u - i, v - j
    return (grid[i, j] * (1 - fu) * (1 - fv) + grid[i + 1, j] * fu * (1 - fv)
            + grid[i, j + 1] * (1 - fu) * fv + grid[i + 1, j + 1] * fu * fv)


def rough_pair(seed: int, n_points: int, n_core: int, size: float = 10.0, levels: int = 9, hurst: float = 0.7,
               sigma: float = 0.3, noise: float = 0.001, change: float = 0.05, quantum: float | None = None):
    """Two epochs of one self-affine surface, independently sampled, plus core points.

    Both epochs: n_points uniform (x, y) in [0, size]^2, z = surface + N(0, noise). The compared
    epoch is raised by a smooth paraboloid bump of height `change` (radius 0.3 size, centred).
    With `quantum`, every coordinate is rounded to a multiple of it (a TLS-like quantised scan).
    Core points: the first n_core reference points (already in random order).
    """
    rng = np.random.default_rng(seed)
    grid = self_affine_grid(rng, levels, hurst, sigma)

    def epoch(bump: float):
        xy = rng.uniform(0.0, size, (n_points, 2))
        z = bilinear(grid, size, xy[:, 0], xy[:, 1]) + rng.normal(0.0, noise, n_points)
        r2 = ((xy[:, 0] - size / 2) ** 2 + (xy[:, 1] - size / 2) ** 2) / (0.3 * size) ** 2
        z = z + bump * np.maximum(0.0, 1.0 - r2)
        pts = np.column_stack([xy, z])
        if quantum is not None:
            pts = np.round(pts / quantum) * quantum
        return np.ascontiguousarray(pts)

    ref, cmp = epoch(0.0), epoch(change)
    return ref, cmp, ref[:n_core].copy()


# ----------------------------------------------------------------------------------------------
# Runs
def run_py4dgeo(ref, cmp, core, D, d, L, threads=2, normals=None):
    """py4dgeo.M3C2 with the equivalents of m3c2's (D, d, L): radii = diameters / 2."""
    import logging

    import py4dgeo

    logging.getLogger("py4dgeo").setLevel(logging.WARNING)  # its kd-tree messages go to stdout
    py4dgeo.set_num_threads(threads)
    kw = dict(corepoint_normals=np.ascontiguousarray(normals)) if normals is not None else {}
    alg = py4dgeo.M3C2(epochs=(py4dgeo.Epoch(np.ascontiguousarray(ref)), py4dgeo.Epoch(np.ascontiguousarray(cmp))),
                       corepoints=np.ascontiguousarray(core), normal_radii=[D / 2], cyl_radius=d / 2, max_distance=L,
                       registration_error=0.0, robust_aggr=False, orientation_vector=np.array([0.0, 0.0, 1.0]), **kw)
    dist, unc = alg.run()
    return dict(distance=np.asarray(dist, float), lod=np.asarray(unc["lodetection"], float),
                n1=np.asarray(unc["num_samples1"], np.int64), n2=np.asarray(unc["num_samples2"], np.int64),
                spread1=np.asarray(unc["spread1"], float), spread2=np.asarray(unc["spread2"], float),
                normal=np.asarray(alg.directions(), float).copy())


def run_m3c2_like_py4dgeo(ref, cmp, core, D, d, L, threads=0):
    """m3c2 in its default mode (sample variance) with no minimum count beyond its own (min_points=1)."""
    return m3c2kit.compare(ref, cmp, core, normal_scale=D, projection_scale=d, max_depth=L, min_points=1,
                        threads=threads)


def agreement(ours_d, ours_lod, theirs_d, theirs_lod, tol):
    """Per core point: |Δdistance| <= tol and |ΔLOD| <= tol, or NaN in both (each separately)."""
    ok_d = (np.abs(ours_d - theirs_d) <= tol) | (np.isnan(ours_d) & np.isnan(theirs_d))
    ok_l = (np.abs(ours_lod - theirs_lod) <= tol) | (np.isnan(ours_lod) & np.isnan(theirs_lod))
    return ok_d & ok_l


# ----------------------------------------------------------------------------------------------
# py4dgeo's known defects, decided from the inputs only (not from either program's output)
FLAG_NONE, FLAG_FEW, FLAG_BOUNDARY = 0, 1, 2
FLAG_NAMES = {FLAG_NONE: "none", FLAG_FEW: "fewer than 3 normal neighbours (b)",
              FLAG_BOUNDARY: "point on a search boundary (a)"}


def boundary_tolerance(*clouds) -> float:
    """1e-9 m, plus 4 ulps of the largest coordinate: py4dgeo measures offsets from segment
    centres c + k n that it rounds to absolute coordinates, which moves them by up to half an ulp
    per component (about 2.3e-10 m at a northing of 4.8e6)."""
    big = max(float(np.abs(c).max()) for c in clouds)
    return 1e-9 + 4 * float(np.spacing(big))


def py4dgeo_defect_flags(ref, cmp, core, normals, D, d, L, which=None, tol=None):
    """FLAG_* per core point (only for the indices in `which`, others FLAG_NONE).

    (b) FLAG_FEW: fewer than 3 reference points strictly within D/2 (py4dgeo's strict ball):
        py4dgeo then leaves the normal uninitialised (distance 0, LOD 0).
    (a) FLAG_BOUNDARY: a point of either cloud within `tol` of a boundary where py4dgeo's
        decision can differ from m3c2's inclusive one: a segment boundary t = -L + 2kL/N
        (k = 0..N, N = ceil(L/r), the ends included) inside the wall, the wall |w| = r within
        the depth, or (reference only) the normal sphere |p - c| = D/2.
    `normals`: m3c2's normals (rows with NaN are skipped: no cylinder was searched).
    """
    from scipy.spatial import cKDTree

    r = d / 2
    N = max(1, int(np.ceil(L / r))) if L >= r else 1
    Lc = L if L >= r else r
    bounds = -Lc + 2 * Lc / N * np.arange(N + 1)
    tol = boundary_tolerance(ref, cmp, core) if tol is None else tol
    idx = np.arange(len(core)) if which is None else np.asarray(which)
    flags = np.zeros(len(core), np.int8)
    reach = np.sqrt((Lc + tol) ** 2 + (r + tol) ** 2)
    trees = [cKDTree(ref), cKDTree(cmp)]
    for i in idx:
        c = core[i]
        near = trees[0].query_ball_point(c, D / 2 + tol)
        dist_ref = np.sqrt(((ref[near] - c) ** 2).sum(1)) if near else np.zeros(0)
        if (dist_ref < D / 2).sum() < 3:
            flags[i] = FLAG_FEW
            continue
        if np.any(np.abs(dist_ref - D / 2) <= tol):
            flags[i] = FLAG_BOUNDARY
            continue
        n = normals[i]
        if not np.all(np.isfinite(n)):
            continue
        for cloud, tree in zip((ref, cmp), trees):
            cand = tree.query_ball_point(c, reach)
            if not cand:
                continue
            v = cloud[cand] - c
            t = v @ n
            w = np.sqrt(((v - np.outer(t, n)) ** 2).sum(1))
            on_seg = (np.abs(t[:, None] - bounds[None, :]) <= tol).any(1) & (w <= r + tol)
            on_wall = (np.abs(w - r) <= tol) & (np.abs(t) <= Lc + tol)
            if np.any(on_seg | on_wall):
                flags[i] = FLAG_BOUNDARY
                break
    return flags
