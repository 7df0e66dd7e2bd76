"""--fdr against a plain run (issue 34: at most 1.05x on 10^6 core points). The same compare of a
flat pair (vertical normals, about 6 points per cylinder) at 10^6 core points, with and without
--fdr 0.05 (BH; BY costs the same ranking), in memory; the best of --repeat runs of each, and the
ranking alone (m3c2::fdr_q_values on the run's p-values).
Run: python bench/fdr_overhead.py [--cores N] [--threads T] [--repeat R] [--method bh|by]."""
import argparse
import time

import numpy as np

import m3c2kit
from m3c2kit import engine


def best(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cores", type=int, default=1_000_000)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--method", choices=("bh", "by"), default="bh")
    a = ap.parse_args()
    rng = np.random.default_rng(0)
    side = int(np.ceil(np.sqrt(a.cores)))  # core points 1 m apart; cylinders d = 1 m, 8 points per m^2
    g = np.arange(side) + 0.5
    cx, cy = np.meshgrid(g, g)
    core = np.c_[cx.ravel(), cy.ravel(), np.zeros(cx.size)][:a.cores]
    n = 8 * side * side
    one = np.c_[rng.uniform(0, side, (n, 2)), rng.normal(0, 0.005, n)]
    two = np.c_[rng.uniform(0, side, (n, 2)), rng.normal(0, 0.005, n)]
    common = dict(projection_scale=1.0, max_depth=0.5, normal_source="vertical", threads=a.threads)
    r = m3c2kit.compare(one, two, core, **common, fdr=0.05, fdr_method=a.method, warn=False)  # warm-up
    plain = best(lambda: m3c2kit.compare(one, two, core, **common, warn=False), a.repeat)
    fdr = best(lambda: m3c2kit.compare(one, two, core, **common, fdr=0.05, fdr_method=a.method, warn=False),
               a.repeat)
    ranking = best(lambda: engine.fdr_q_values(r.p_value, a.method), a.repeat)
    print(f"{len(core)} core points, {n} points per cloud, {a.threads} threads, best of {a.repeat}")
    print(f"plain run: {plain:.3f} s")
    print(f"--fdr 0.05 --fdr-method {a.method}: {fdr:.3f} s")
    print(f"ratio: {fdr / plain:.3f} (target <= 1.05)")
    print(f"the ranking alone: {ranking:.3f} s ({int(r.significant_fdr.sum())} discoveries)")


if __name__ == "__main__":
    main()
