"""The variogram of 10^6 stable core points (sampled pairs) on 2 threads: issue 34 asks <= 10 s.
Prints the time of m3c2kit.analysis.variogram's empirical variogram (the C++ pair sums) and of
the fit. Run: python bench/variogram.py [--points N] [--threads T]."""
import argparse
import time

import numpy as np

from m3c2kit.analysis.error_model import Component, ErrorModel
from m3c2kit.analysis.random_fields import sample_field
from m3c2kit.analysis.variogram import empirical_variogram, fit_model


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--points", type=int, default=1_000_000)
    ap.add_argument("--threads", type=int, default=2)
    a = ap.parse_args()
    side = int(np.sqrt(a.points))
    g = np.arange(side, dtype=np.float64)
    x, y = np.meshgrid(g, g)
    xy = np.c_[x.ravel(), y.ravel()]
    values = sample_field(xy, ErrorModel(1e-5, (Component("spherical", 1e-4, 50.0),)), 1, include_nugget=True)
    points = np.c_[xy, np.zeros(len(xy))]
    t = time.perf_counter()
    emp = empirical_variogram(points, values, seed=0, threads=a.threads)
    t_pairs = time.perf_counter() - t
    t = time.perf_counter()
    model, kept = fit_model(emp)
    t_fit = time.perf_counter() - t
    print(f"{len(points)} stable core points, {a.threads} threads: pair sums {t_pairs:.2f} s "
          f"({int(emp.pairs.sum())} pairs), fit {t_fit:.2f} s, total {t_pairs + t_fit:.2f} s; {kept}")


if __name__ == "__main__":
    main()
