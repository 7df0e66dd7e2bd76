"""Benchmark of the Kalman filter and RTS smoother (include/m3c2/kalman.hpp; docs/series.md,
"Kalman filter"): prints figures, asserts nothing.

1. 100 epochs x 100k core points: ours (the engine, blocks of core points as `m3c2 series
   kalman` runs them) against the tum-rsa py4dgeo fork's `kalman_smooth_m3c2_series` (filterpy,
   one core point at a time), the same model (discrete noise, its prior) and the same thread
   count. The reference runs on a sample of core points in its own Python (--python, with filterpy)
   and its time is scaled to 100k core points, divided by the thread count (its best case:
   perfect scaling over processes).
2. The same series under the shared observation model (the default of `m3c2 series kalman`:
   the state also holds the reference's error, each epoch's variance from the pooled scatter),
   beside the independent model's time (its 2-state filter, as above but started at the first
   observation).
3. 1,000 epochs x 100k core points on 2 threads, block by block, with progress.

    .venv/bin/python bench/kalman.py --python /tmp/kalman_ref_venv/bin/python \\
        --tum-rsa py4dgeo-kalmanfiltering/src/py4dgeo/m3c2_kalman.py [--threads 2] [--skip-long]"""
from __future__ import annotations

import argparse
import importlib.util
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

SEED = 7
BLOCK = 10_000  # core points per block: memory ~ BLOCK x epochs x 15 x 8 bytes


def series(rng, cores: int, epochs: int):
    days = np.cumsum(rng.uniform(0.05, 0.2, epochs))
    z = 0.01 * np.sin(days)[None, :] + rng.normal(0, 0.01, (cores, epochs))
    z[rng.random(z.shape) < 0.05] = np.nan
    return days, z, np.full((cores, epochs), 0.01)


def reference_side(path: str, cores: int, epochs: int) -> None:
    spec = importlib.util.spec_from_file_location("m3c2_kalman", path)
    tum = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tum)
    days, z, sd = series(np.random.default_rng(SEED), cores, epochs)
    dts = np.diff(days, prepend=days[0])
    dts[0] = dts[1]
    start = time.process_time()
    for c in range(cores):
        tum.kalman_smooth_m3c2_series(z[c], sd[c], dts, process_sigma=0.01)
    print(time.process_time() - start)


def ours(days, z, var, threads: int, *, prior: bool, progress=False) -> float:
    """Wall seconds of the engine over every block (moments, outputs: one block at a time)."""
    from m3c2kit import engine
    p = engine.kalman_params(order=2, discrete_noise=True, process_noise=1e-4, initial_variance=(1.0, 1.0, 1.0),
                             prior_time=(days[0] - (days[1] - days[0])) if prior else None,
                             observation="independent")
    start = time.perf_counter()
    for b in range(0, len(z), BLOCK):
        zb = np.ascontiguousarray(z[b:b + BLOCK])
        moments = np.empty((len(zb), z.shape[1], 5))
        mean = None
        if prior:
            first = np.array([row[np.isfinite(row)][0] for row in zb])
            mean = np.column_stack([first, np.zeros(len(zb))])
        engine.kalman_smooth(zb, np.ascontiguousarray(var[b:b + BLOCK]), days, moments, p, prior_mean=mean,
                             threads=threads)
        if progress:
            print(f"  {min(len(z), b + BLOCK):>7,} / {len(z):,} core points, {time.perf_counter() - start:.1f} s",
                  flush=True)
    return time.perf_counter() - start


def ours_shared(days, z, threads: int) -> float:
    """Wall seconds of the shared model over every block, spreads as a store holds them (sigma 0.01
    for 10 points a side), anchored a step before the first epoch."""
    from m3c2kit import engine
    p = engine.kalman_params(order=2, discrete_noise=True, process_noise=1e-4, initial_variance=(1.0, 1.0, 1.0),
                             reference=(days[0] - (days[1] - days[0]), None))
    start = time.perf_counter()
    for b in range(0, len(z), BLOCK):
        zb = np.ascontiguousarray(z[b:b + BLOCK])
        sigma, count = np.full(zb.shape, 0.01 * np.sqrt(10 / 2)), np.full(zb.shape, 10.0)
        moments = np.empty((len(zb), z.shape[1], 9))
        engine.kalman_smooth(zb, None, days, moments, p, spread=(sigma, count, sigma, count), threads=threads)
    return time.perf_counter() - start


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--python", help="a Python with filterpy (the reference's)")
    p.add_argument("--tum-rsa", help="the tum-rsa fork's src/py4dgeo/m3c2_kalman.py")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--cores", type=int, default=100_000)
    p.add_argument("--sample", type=int, default=300, help="core points the reference runs (scaled)")
    p.add_argument("--skip-long", action="store_true", help="skip the 1,000-epoch run")
    p.add_argument("--reference-side", nargs=3, help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.reference_side:
        reference_side(args.reference_side[0], int(args.reference_side[1]), int(args.reference_side[2]))
        return 0
    rng = np.random.default_rng(SEED)
    days, z, sd = series(rng, args.cores, 100)
    wall = ours(days, z, sd ** 2, args.threads, prior=True)
    print(f"ours, 100 epochs x {args.cores:,} core points, {args.threads} thread(s): {wall:.2f} s")
    plain = ours(days, z, sd ** 2, args.threads, prior=False)
    shared = ours_shared(days, z, args.threads)
    print(f"ours, --observation independent / shared, the same series: {plain:.2f} s / {shared:.2f} s")
    if args.python and args.tum_rsa:
        with tempfile.TemporaryDirectory() as tmp:  # py4dgeo writes its py4dgeo.log into the working directory
            out = subprocess.run([args.python, os.path.abspath(__file__), "--reference-side",
                                  os.path.abspath(args.tum_rsa), str(args.sample), "100"],
                                 check=True, capture_output=True, text=True, cwd=tmp).stdout
        per_core = float(out.strip().splitlines()[-1]) / args.sample
        scaled = per_core * args.cores / args.threads
        print(f"tum-rsa fork (filterpy), {args.sample} core points: {per_core * 1e3:.2f} ms CPU each; "
              f"{args.cores:,} core points on {args.threads} process(es), perfect scaling: {scaled:.0f} s")
        print(f"ours is {scaled / wall:.0f}x faster")
    if not args.skip_long:
        del z, sd
        days, z, sd = series(np.random.default_rng(SEED + 1), args.cores, 1000)
        print(f"1,000 epochs x {args.cores:,} core points, 2 threads (blocks of {BLOCK:,}):")
        wall = ours(days, z, sd ** 2, 2, prior=False, progress=True)
        print(f"ours, 1,000 epochs x {args.cores:,} core points, 2 threads: {wall:.1f} s ({wall / 60:.2f} min)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
