"""--error-model against a plain run (issue 34: at most 1.3x). The same compare of a flat pair
(vertical normals), with and without an error model; the best of --repeat runs of each.
Run: python bench/error_model.py [--points N] [--threads T]."""
import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

import m3c2kit
from m3c2kit.analysis.error_model import Component, ErrorModel, save


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--points", type=int, default=1_000_000)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    rng = np.random.default_rng(0)
    side = np.sqrt(a.points) / 4  # 16 points per m^2
    one = np.c_[rng.uniform(0, side, (a.points, 2)), rng.normal(0, 0.005, a.points)]
    two = np.c_[rng.uniform(0, side, (a.points, 2)), rng.normal(0, 0.005, a.points)]
    g = np.arange(0.5, side, 0.5)
    cx, cy = np.meshgrid(g, g)
    core = np.c_[cx.ravel(), cy.ravel(), np.zeros(cx.size)]
    common = dict(projection_scale=1.0, max_depth=0.5, normal_source="vertical", threads=a.threads)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "model.json"
        save(path, ErrorModel(0.0, (Component("spherical", 1e-4, 5.0),), 1.0))
        times = {}
        for name, extra in (("plain", {}), ("--error-model", {"error_model": str(path)})):
            best = np.inf
            for _ in range(a.repeat):
                t = time.perf_counter()
                m3c2kit.compare(one, two, core, **common, **extra)
                best = min(best, time.perf_counter() - t)
            times[name] = best
    print(f"{a.points} points per cloud, {len(core)} core points, {a.threads} threads: plain {times['plain']:.3f} s, "
          f"--error-model {times['--error-model']:.3f} s, ratio {times['--error-model'] / times['plain']:.3f}")


if __name__ == "__main__":
    main()
