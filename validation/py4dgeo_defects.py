"""Minimal inputs that reproduce py4dgeo's known M3C2 defects (issue 4; docs/validation.md).

Each case prints what py4dgeo returns, the exact answer (derived by hand from the tiny input and
checked with numpy), and what m3c2 returns. Run in the validation environment:

    PYTHONPATH=python /tmp/valenv/bin/python validation/py4dgeo_defects.py

All inputs are tiny, exact binary fractions (multiples of 1/8), so no rounding is involved: the
differences are decisions, not precision.
"""
from __future__ import annotations

import logging

import numpy as np

import m3c2kit

import py4dgeo  # noqa: E402

logging.getLogger("py4dgeo").setLevel(logging.WARNING)  # its kd-tree messages

py4dgeo.set_num_threads(1)
Z95 = 1.959963984540054


def p4(ref, cmp, core, radii, r, L, normals=None):
    kw = {} if normals is None else dict(corepoint_normals=np.asarray(normals, float))
    alg = py4dgeo.M3C2(epochs=(py4dgeo.Epoch(ref), py4dgeo.Epoch(cmp)), corepoints=core, normal_radii=list(radii),
                       cyl_radius=r, max_distance=L, orientation_vector=np.array([0.0, 0.0, 1.0]), **kw)
    d, u = alg.run()
    return d, u, alg.directions()


def flat_grid(z, half=1.0, step=0.125):
    """A square grid of points at height z, x and y in [-half, half] by `step` (exact binary values)."""
    g = np.arange(-half, half + step / 2, step)
    x, y = np.meshgrid(g, g)
    return np.column_stack([x.ravel(), y.ravel(), np.full(x.size, float(z))])


def pca_normal(pts):
    """Unit eigenvector of the smallest eigenvalue of the points' covariance, oriented +z."""
    w, v = np.linalg.eigh(np.cov(pts.T))
    n = v[:, 0]
    return n if n[2] >= 0 else -n


def fmt(v):
    return np.array2string(np.asarray(v, float), precision=6, suppress_small=True, floatmode="fixed")


def segment_boundaries():
    print("### Defect (a): points on a boundary of the stepped cylinder search\n")
    print("Reference: flat 17 x 17 grid (step 0.125 m) at z = 0; compared: the same grid at z = 0.25.")
    print("Core point (0, 0, 0), normal imposed (0, 0, 1), cylinder radius r = 0.25 (d = 0.5).")
    print("Exact answer at every depth L >= 0.25: n1 = n2 = 13 (grid points with x^2 + y^2 <= r^2),")
    print("distance = 0.25, LOD = 0 (both surfaces exactly flat). py4dgeo cuts [-L, L] into N = ceil(L/r)")
    print("segments of length 2L/N and keeps points strictly inside one; m3c2 keeps t in [-L, L].\n")
    ref, cmp = flat_grid(0.0), flat_grid(0.25)
    core = np.array([[0.0, 0.0, 0.0]])
    print("| L | N | segment boundaries | py4dgeo distance | py4dgeo n1, n2 | exact distance | exact n1, n2 | m3c2 distance | m3c2 n1, n2 |")
    print("|---|---|---|---|---|---|---|---|---|")
    for L in (0.25, 0.5, 0.75, 1.0, 1.25):
        N = int(np.ceil(L / 0.25))
        b = -L + 2 * L / N * np.arange(N + 1)
        d, u, _ = p4(ref, cmp, core, [0.5], 0.25, L, normals=[[0.0, 0.0, 1.0]])
        r = m3c2kit.compare(ref, cmp, core, projection_scale=0.5, max_depth=L, normal_source="core",
                         core_normals=[[0.0, 0.0, 1.0]], min_points=1)
        print(f"| {L} | {N} | {', '.join(f'{x:g}' for x in b)} | {d[0]} | {u['num_samples1'][0]}, {u['num_samples2'][0]} "
              f"| 0.25 | 13, 13 | {r.distance[0]} | {r.n1[0]}, {r.n2[0]} |")
    print("\nEvery depth here loses a whole surface (distance NaN) or the reference plane sits on the")
    print("boundary t = 0 of an even N. On real data only the points within rounding of a boundary are")
    print("affected, counted 0, 1 or 2 times: a core point that is itself a reference point lies at t = 0.\n")


def fewer_than_three():
    print("### Defect (b): fewer than 3 neighbours for the normal\n")
    ref = np.array([[0.0, 0.0, 0.0], [0.125, 0.0, 0.0], [5.0, 5.0, 0.0], [5.125, 5.0, 0.0], [5.0, 5.125, 0.0]])
    cmp = ref + [0.0, 0.0, 0.5]
    core = np.array([[0.0, 0.0, 0.0]])
    print("Reference: 2 points within the normal radius 0.5 of the core point (0, 0, 0) and 3 far away;")
    print("compared: the same raised by 0.5. Normal radius 0.5 (D = 1), r = 0.5, L = 1.5 (N = 3, no")
    print("segment boundary at t = 0).")
    print("Exact answer: no plane through 2 points, so no normal, no distance (undefined).\n")
    d, u, n = p4(ref, cmp, core, [0.5], 0.5, 1.5)
    r = m3c2kit.compare(ref, cmp, core, normal_scale=1.0, projection_scale=1.0, max_depth=1.5, min_points=1)
    print(f"- py4dgeo: normal {fmt(n[0])} (never computed), distance {d[0]}, LOD {u['lodetection'][0]}, "
          f"n1 {u['num_samples1'][0]}, n2 {u['num_samples2'][0]}")
    print("- exact: normal undefined, distance undefined")
    print(f"- m3c2: normal {fmt(r.normal[0])}, distance {r.distance[0]}, LOD {r.lod[0]}, "
          f"status {m3c2kit.STATUS_NAMES[r.status[0]]}\n")


def multiscale_recount():
    print("### Defect (c): multi-scale neighbours counted again at the next radius\n")
    # Inner points (within 0.3): a tilted, non-planar cluster; outer ring (0.3 < |p| < 1): a flat plane.
    inner = np.array([[0.0, 0.0, 0.0], [0.125, 0.0, 0.125], [0.0, 0.125, -0.125], [-0.125, -0.125, 0.25],
                      [0.125, 0.125, 0.0], [-0.125, 0.125, 0.125]])
    g = flat_grid(0.0, half=0.875, step=0.125)
    rad = np.sqrt((g[:, :2] ** 2).sum(1))
    outer = g[(rad > 0.375) & (rad < 0.875)]
    ref = np.vstack([inner, outer])
    cmp = ref + [0.0, 0.0, 0.25]
    core = np.array([[0.0, 0.0, 0.0]])
    print(f"Reference: {len(inner)} irregular points near the core point (0, 0, 0) and {len(outer)} points of the")
    print("plane z = 0 between 0.375 and 0.875 from it. normal_radii = [0.3, 1.0]: the second radius holds")
    print(f"all {len(ref)} points; py4dgeo keeps the largest planarity, the second radius.\n")
    _, _, n_two = p4(ref, cmp, core, [0.3, 1.0], 0.25, 1.0)
    _, _, n_one = p4(ref, cmp, core, [1.0], 0.25, 1.0)
    exact = pca_normal(ref)
    first = ref[np.sqrt((ref ** 2).sum(1)) < 0.3]  # py4dgeo's strict ball at the first radius
    twice = pca_normal(np.vstack([first, ref]))
    r = m3c2kit.normals(ref, core, normal_scale=2.0)

    def deg(a, b):
        return np.degrees(np.arccos(min(1.0, abs(float(np.dot(a, b))))))

    print(f"- py4dgeo, normal_radii=[0.3, 1.0]: normal {fmt(n_two[0])}")
    print(f"- py4dgeo, normal_radii=[1.0]:      normal {fmt(n_one[0])}")
    print(f"- exact, PCA of the {len(ref)} points within 1.0: {fmt(exact)}")
    print(f"- PCA with the {len(first)} points within 0.3 counted twice ({len(ref) + len(first)} points): {fmt(twice)}")
    print(f"- m3c2 normal at D = 2.0 (m3c2 sums each scale's own neighbours): {fmt(r['normal'][0])}")
    print(f"\nAngle between py4dgeo's two-radius normal and the exact one: {deg(n_two[0], exact):.6f} degrees;")
    print(f"and the PCA with the first radius' points counted twice: {deg(n_two[0], twice):.2e} degrees.")
    print(f"m3c2 vs exact: {deg(r['normal'][0], exact):.2e} degrees. The effect grows with the share of")
    print("points inside the smaller radii (each smaller radius' neighbours are added once more).\n")


def main():
    print(f"py4dgeo {py4dgeo.__version__}, m3c2 {m3c2kit.__version__}, numpy {np.__version__}\n")
    segment_boundaries()
    fewer_than_three()
    multiscale_recount()


if __name__ == "__main__":
    main()
