"""M3C2-EP speed (issue 16): m3c2kit's plain M3C2 and ``uncertainty ep`` on one simulated pair,
and py4dgeo's M3C2EP on the same inputs (bench environment: ``pip install py4dgeo``).

    python bench/uncertainty_bench.py [--points 1000000] [--core 100000] [--threads 2]
        [--py4dgeo-core 2000]

The pair: the validation simulator's scene (validation/uncertainty_sim.py: three scanners with
range and angle noise, a 10 x 10 m rough surface) with --points points per epoch, --core core
points, normals imposed vertical (all three tools get the same normals). m3c2kit runs with
--threads threads, each timed as its best of 3 runs; py4dgeo's M3C2EP runs on its hard-coded 4
processes (it has no thread setting) on the first --py4dgeo-core core points (its full run would
take hours): its time per core point is scaled to --core and printed as such.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from m3c2kit import _core
from m3c2kit.run import uncertainty_inputs as ui

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "validation"))
import uncertainty_sim as sim  # noqa: E402


def best_of(fn, runs=3):
    best, out = np.inf, None
    for _ in range(runs):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return best, out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--points", type=int, default=1_000_000)
    ap.add_argument("--core", type=int, default=100_000)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--py4dgeo-core", type=int, default=2000)
    a = ap.parse_args()
    rng = np.random.default_rng(1)
    sim.POINTS_PER_SCAN = a.points // len(sim.SCANNERS)
    ref, ids1 = sim.scan(rng)
    cmp_, ids2 = sim.scan(rng)
    core = sim.core_points(rng, a.core)
    normals = np.tile([0.0, 0.0, 1.0], (len(core), 1))
    table, cxx = sim.table(), sim.alignment_covariance()
    tfm = sim.drawn_transform(rng)
    p = _core.Params()
    p.normal_source = _core.NormalSource.core
    p.projection_diameter, p.max_depth, p.min_points = 0.5, 0.3, 5
    print(f"pair: {len(ref)} + {len(cmp_)} points, {len(core)} core points, d = 0.5, L = 0.3, threads {a.threads}")
    moved = (cmp_ - sim.REDUCTION) @ tfm[:, :3].T + tfm[:, 3] + sim.REDUCTION
    t_plain, plain = best_of(lambda: ui.compute(ref, moved, core, p, core_normals=normals, threads=a.threads))
    p.uncertainty = _core.Uncertainty.ep
    ep = ui.EpInputs(table, table, ids1, ids2, tfm, cxx, sim.REDUCTION)
    t_ep, out = best_of(lambda: ui.compute(ref, cmp_, core, p, core_normals=normals, threads=a.threads, ep=ep))
    print(f"m3c2kit plain M3C2 (eq. 1): {t_plain:.3f} s   mean points per cylinder {plain['n1'].mean():.1f}")
    print(f"m3c2kit uncertainty ep:     {t_ep:.3f} s   ({t_ep / t_plain:.2f}x plain)")
    try:
        import py4dgeo
    except ImportError:
        print("py4dgeo not installed: its row is skipped")
        return
    k = min(a.py4dgeo_core, len(core))
    e1 = py4dgeo.Epoch(ref, scanpos_info={str(int(r[0])): {"origin": list(r[1:4]), "sigma_range": r[4],
                                                             "sigma_scan": r[6], "sigma_yaw": r[7]} for r in table})
    e1.scanpos_id = ids1.astype(np.int32)
    e2 = py4dgeo.Epoch(cmp_, scanpos_info=e1.scanpos_info)
    e2.scanpos_id = ids2.astype(np.int32)
    alg = py4dgeo.M3C2EP(epochs=(e1, e2), corepoints=core[:k], corepoint_normals=normals[:k], cyl_radius=0.25,
                         max_distance=0.3, tfM=tfm, Cxx=cxx, refPointMov=sim.REDUCTION)
    t = time.perf_counter()
    alg.run()
    t_p4 = time.perf_counter() - t
    scaled = t_p4 / k * len(core)
    print(f"py4dgeo M3C2EP (4 processes) on {k} core points: {t_p4:.1f} s -> {scaled:.0f} s for {len(core)} "
          f"core points (scaled per core point)")
    print(f"ratio py4dgeo M3C2EP / m3c2kit ep: {scaled / t_ep:.0f}x")


if __name__ == "__main__":
    main()
