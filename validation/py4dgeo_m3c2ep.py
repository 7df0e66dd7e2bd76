"""py4dgeo's M3C2EP against m3c2kit's ``uncertainty ep`` (issue 16; docs/validation.md#m3c2-ep-and-py4dgeo).

Bench environment only (``pip install py4dgeo`` in a venv; no test imports this):

    python validation/py4dgeo_m3c2ep.py

Part 1 reproduces, on minimal inputs through py4dgeo's public API, the three defects of its
code (py4dgeo 1.2.0, ``m3c2ep.py``): the two angular sigmas swapped, the range sigma reused as
a distance-dependent term (sqrt(a^2 + a 1e-6 r^2)), and the distance sign opposite to its own
M3C2. Part 2 runs both on the same simulated pair with m3c2kit set to py4dgeo's model (matrix
weights, mean-of-points covariance, published LoD, at least 5 points) and py4dgeo's inputs
compensated for the defects (sigmas swapped back, the range term as our ppm term, the sign
flipped): they agree to 1e-6 where the transformation is the identity. With a real tfM they
differ by what py4dgeo's Jacobians at the transformed (instead of the measured) coordinates give.
"""
from __future__ import annotations

import logging
import sys
from pathlib import Path

import numpy as np
import py4dgeo

from m3c2kit import _core
from m3c2kit.run import uncertainty_inputs as ui

sys.path.insert(0, str(Path(__file__).resolve().parent))
import uncertainty_sim as sim  # noqa: E402

logging.getLogger("py4dgeo").setLevel(logging.WARNING)
SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "pairs" / "ahk-corepoints-m3c2ep"


def sps_dict(table):
    return {str(int(r[0])): {"origin": list(r[1:4]), "sigma_range": r[4], "sigma_scan": r[6], "sigma_yaw": r[7]}
            for r in table}


def epoch(points, ids, table):
    e = py4dgeo.Epoch(np.ascontiguousarray(points), scanpos_info=sps_dict(table))
    e.scanpos_id = ids.astype(np.int32)
    return e


def run_py4dgeo(ref, ids1, cmp_, ids2, table, core, normals, r, L, tfm=None, cxx=None, red=None):
    alg = py4dgeo.M3C2EP(epochs=(epoch(ref, ids1, table), epoch(cmp_, ids2, table)), corepoints=core,
                         corepoint_normals=normals, cyl_radius=float(r), max_distance=float(L),
                         tfM=np.eye(3, 4) if tfm is None else tfm, Cxx=np.zeros((12, 12)) if cxx is None else cxx,
                         refPointMov=np.zeros(3) if red is None else red)
    d, u, cov = alg.run()
    return d, u, cov


def ours_as_py4dgeo(ref, ids1, cmp_, ids2, table, core, normals, r, L, tfm, cxx, red):
    """m3c2kit with py4dgeo's model and py4dgeo's defects compensated in the inputs."""
    t = table.copy()
    t[:, 5] = np.sqrt(table[:, 4]) * 1e3  # sqrt(a^2 + a 1e-6 r^2) == sqrt(a^2 + (b 1e-6 r)^2), b = sqrt(a) 1e3
    t[:, 6], t[:, 7] = table[:, 7], table[:, 6]  # py4dgeo's yaw uses sigma_scan and its scan sigma_yaw
    p = _core.Params()
    p.normal_source = _core.NormalSource.core
    p.projection_diameter, p.max_depth, p.min_points = 2 * r, L, 5
    p.uncertainty = _core.Uncertainty.ep
    p.ep_weights, p.ep_covariance, p.ep_lod = _core.EpWeights.matrix, _core.EpCovariance.mean_of_points, _core.EpLod.published
    return ui.compute(ref, cmp_, core, p, core_normals=normals, covariances=True,
                      ep=ui.EpInputs(t, t, ids1, ids2, tfm, cxx, red))


def grid(centre, axes, half=0.05, step=0.025):
    g = np.arange(-half, half + step / 2, step)
    a, b = np.meshgrid(g, g)
    return centre + a.ravel()[:, None] * axes[0] + b.ravel()[:, None] * axes[1]


def defects():
    print("== Part 1: minimal reproductions ==")
    # A 5x5 patch on the plane x = 10, 10 m from a scanner at the origin, looking horizontally.
    patch = grid(np.array([10.0, 0.0, 0.0]), (np.array([0, 1.0, 0]), np.array([0, 0, 1.0])))
    ids = np.ones(len(patch), np.int32)
    core = np.array([[10.0, 0.0, 0.0]])
    # 1. sigma_scan (vertical angle) 1 mrad, sigma_yaw (horizontal) 1e-6: the points' error is
    # vertical, 10 m x 1 mrad = 10 mm along z, ~0 along y.
    table = np.array([[1, 0.0, 0.0, 0.0, 1e-6, 0.0, 1e-3, 1e-6]])
    for n, axis in ((np.array([[0, 0, 1.0]]), "z"), (np.array([[0, 1.0, 0]]), "y")):
        _, u, _ = run_py4dgeo(patch, ids, patch, ids, table, core, n, 0.5, 0.5)
        print(f"1. angular sigmas: spread1 along {axis}: py4dgeo {u['spread1'][0]:.6f}, "
              f"expected {0.01 if axis == 'z' else 1e-5:.6f} (scan error is vertical)")
    # 2. sigma_range 5 mm, angles ~0, a point 100 m away along x: range variance 2.5e-5.
    far = grid(np.array([100.0, 0.0, 0.0]), (np.array([0, 1.0, 0]), np.array([0, 0, 1.0])))
    table = np.array([[1, 0.0, 0.0, 0.0, 0.005, 0.0, 1e-9, 1e-9]])
    _, u, _ = run_py4dgeo(far, ids, far, ids, table, np.array([[100.0, 0, 0]]), np.array([[1.0, 0, 0]]), 0.5, 0.5)
    print(f"2. range sigma: spread1 along the beam: py4dgeo {u['spread1'][0]:.6f}, expected 0.005000 "
          f"(py4dgeo: sqrt(0.005^2 + 0.005e-6 * 100^2) = {np.sqrt(0.005**2 + 0.005e-6 * 1e4):.6f})")
    # 3. The compared patch 0.1 above the reference, normal +z.
    flat = grid(np.array([10.0, 0.0, 0.0]), (np.array([1.0, 0, 0]), np.array([0, 1.0, 0])))
    up = flat + [0, 0, 0.1]
    table = np.array([[1, 0.0, 0.0, 5.0, 0.005, 0.0, 1e-3, 1e-3]])
    d, _, _ = run_py4dgeo(flat, ids, up, ids, table, core, np.array([[0, 0, 1.0]]), 0.5, 0.5)
    m = py4dgeo.M3C2(epochs=(py4dgeo.Epoch(flat), py4dgeo.Epoch(up)), corepoints=core, cyl_radius=0.5,
                     max_distance=0.5, corepoint_normals=np.array([[0, 0, 1.0]]))
    d_m3c2, _ = m.run()
    print(f"3. sign: compared 0.1 above the reference: py4dgeo M3C2 {d_m3c2[0]:+.6f}, M3C2EP {d[0]:+.6f} "
          f"(m3c2kit: +0.100000 for both)")


def agreement():
    print("\n== Part 2: agreement on a simulated pair ==")
    rng = np.random.default_rng(16)
    sim.POINTS_PER_SCAN = 3000
    ref, ids1 = sim.scan(rng)
    cmp_, ids2 = sim.scan(rng)
    table = sim.table()
    core = sim.core_points(rng, 300)
    normals = np.tile([0.0, 0.0, 1.0], (len(core), 1))
    r, L = 0.25, 0.3
    cases = [("identity tfM, simulator's Cxx", np.eye(3, 4), sim.alignment_covariance(), sim.REDUCTION)]
    if SHARED.exists():  # the AHK case's real tfM, Cxx and reduction point, moved to this scene
        tfm = ui.load_matrix(SHARED / "tfM.csv", (3, 4), "--transform")
        cxx = ui.load_matrix(SHARED / "Cxx.csv", (12, 12), "--alignment-covariance")
        cxx = 0.5 * (cxx + cxx.T)
        cases.append(("AHK tfM and Cxx about (0, 0, 0)", tfm, cxx, np.zeros(3)))
    for name, tfm, cxx, red in cases:
        d, u, cov = run_py4dgeo(ref, ids1, cmp_, ids2, table, core, normals, r, L, tfm, cxx, red)
        o = ours_as_py4dgeo(ref, ids1, cmp_, ids2, table, core, normals, r, L, tfm, cxx, red)
        both = np.isfinite(d) & np.isfinite(o["distance"])
        print(f"{name}: {both.sum()} of {len(core)} core points computed by both "
              f"(py4dgeo only {np.sum(np.isfinite(d) & ~both)}, ours only {np.sum(np.isfinite(o['distance']) & ~both)})")
        report(d, u, cov, o, both)
        if not np.allclose(tfm, np.eye(3, 4)):
            # py4dgeo's Jacobians (angles and alignment) at the transformed coordinates: ours given
            # the compared cloud already moved, as if measured there (tfM's rotation kept for R S R^T
            # would differ by 1e-4 only; the identity is used).
            moved = (cmp_ - red) @ tfm[:, :3].T + tfm[:, 3] + red
            o2 = ours_as_py4dgeo(ref, ids1, moved, ids2, table, core, normals, r, L, np.eye(3, 4), cxx, red)
            print("   ours with the Jacobians at the transformed coordinates, as py4dgeo:")
            report(d, u, cov, o2, both)


def report(d, u, cov, o, both):
    for label, theirs, mine in (("distance (sign flipped)", -d, o["distance"]), ("LoD", u["lodetection"], o["lod"]),
                                ("spread1", u["spread1"], o["spread1"]), ("spread2", u["spread2"], o["spread2"]),
                                ("cov2", cov["cov2"], o["covariance2"])):
        a, b = np.asarray(theirs)[both], np.asarray(mine)[both]
        rel = np.max(np.abs(a - b) / np.maximum(np.abs(a), 1e-12))
        print(f"   {label:24s} max |diff| {np.max(np.abs(a - b)):.3e}   max relative {rel:.3e}")


if __name__ == "__main__":
    py4dgeo.set_num_threads(1)
    defects()
    agreement()
