"""TAM3C2: ours (include/m3c2/tam3c2.hpp) against the authors' code (xyuhuang/py4dgeo,
src/py4dgeo/tam3c2.py: a Python loop per core point, one thread) on the same synthetic series,
the same thread count (1), and ours on 2 threads (docs/series.md, "TAM3C2").

    .venv/bin/python bench/tam3c2.py --python /tmp/tam_ref_venv/bin/python --tam3c2 PATH/tam3c2.py \\
        [--epochs 100] [--core 100000] [--reference-core 200]

The reference runs on --reference-core core points (its time per core point is scaled to --core:
its loop is per core point, so the scaling is linear); ours on all of them, --block core points at
a time (the results of one block in memory, as the command's blocks), on each of --threads.
Prints CPU seconds and progress per block. 1,000 epochs x 100k core points, ours only:

    .venv/bin/python bench/tam3c2.py --epochs 1000 --threads 2

--fallback m3c2 and --window-breaks changepoints time our extensions (docs/series.md, "TAM3C2"),
given a stand-in per-epoch M3C2 (the slope's rise at each epoch, 5 mm noise, 20 % without a
distance)."""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

SETTINGS = dict(normal_radii=[0.5, 1.0], window_ratios=[0.2], min_points=10, cylinder_radius=0.5, max_distance=2.0,
                sigma_ratio=1.0, registration_error=0.0)


def series(n_epochs: int, n_core: int, seed: int = 1):
    """Epochs of a 100 m x 100 m rough slope, 2 to 20 points per m^2, hourly with gaps, rising
    0.3 m over the series whatever its length (inside the cylinder's half-length: a surface that
    left the cylinder would make every side walk its whole window, a different benchmark)."""
    rng = np.random.default_rng(seed)
    hours = np.cumsum(rng.integers(1, 6, n_epochs)).astype(float)
    side = max(10.0, min(100.0, np.sqrt(n_core)))  # about one core point per m^2
    clouds = []
    for h in hours:
        n = int(side * side * rng.choice([2, 5, 20]))
        x, y = rng.uniform(0, side, n), rng.uniform(0, side, n)
        z = 0.1 * x + 0.2 * np.sin(y / 3) + 0.3 * h / hours[-1] + rng.normal(0, 0.01, n)
        clouds.append(np.column_stack([x, y, z]))
    core = np.column_stack([rng.uniform(1, side - 1, n_core), rng.uniform(1, side - 1, n_core), np.zeros(n_core)])
    core[:, 2] = 0.1 * core[:, 0] + 0.2 * np.sin(core[:, 1] / 3)
    return hours, clouds, core


def stand_in_m3c2(hours, n: int, seed: int) -> dict:
    """A per-epoch M3C2 for the extensions to read: the series' rise, noise, 20 % NaN."""
    rng = np.random.default_rng(seed)
    d = 0.3 * (hours - hours[0]) / hours[-1] + rng.normal(0, 0.005, (n, len(hours)))
    d[rng.random(d.shape) < 0.2] = np.nan
    d[:, 0] = 0.0
    other = np.where(np.isnan(d), np.nan, 1.0)
    return {"distance": d, "lod": 0.01 * other, "significant": other, "n1": 10 * other, "n2": 3 * other}


def _reference(args) -> None:
    import datetime as dt
    import importlib.util
    import py4dgeo
    spec = importlib.util.spec_from_file_location("tam3c2_reference", args.tam3c2)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    hours, clouds, core = series(args.epochs, args.core)
    core = core[: args.reference_core]
    start = dt.datetime(2024, 1, 1)
    epochs = [py4dgeo.Epoch(c, timestamp=start + dt.timedelta(hours=float(h))) for c, h in zip(clouds, hours)]
    tam = module.TAM3C2(epochs_timeseries=epochs, max_window_ratio=SETTINGS["window_ratios"],
                        normal_radii=SETTINGS["normal_radii"], required_points=SETTINGS["min_points"],
                        weighting=module.Weighting("gaussian"), corepoints=core,
                        cyl_radius=SETTINGS["cylinder_radius"], max_distance=SETTINGS["max_distance"])
    t0 = time.process_time()
    for e in epochs[1:]:
        tam.calculate_distances(epochs[0], e)
    print(json.dumps({"cpu_s": time.process_time() - t0, "core": len(core)}))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--python")
    ap.add_argument("--tam3c2")
    ap.add_argument("--epochs", type=int, default=100)
    ap.add_argument("--core", type=int, default=100_000)
    ap.add_argument("--reference-core", type=int, default=200)
    ap.add_argument("--block", type=int, default=10_000, help="core points a call (default 10,000)")
    ap.add_argument("--threads", type=lambda t: [int(v) for v in t.split(",")], default=[1, 2],
                    help="thread counts to time, comma-separated (default 1,2)")
    ap.add_argument("--fallback", default="none", help="none (the authors' rule) or m3c2")
    ap.add_argument("--window-breaks", default="none", help="none (the authors' rule) or changepoints")
    ap.add_argument("--reference-side", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.reference_side:
        _reference(args)
        return 0
    from m3c2kit import engine as facade
    hours, clouds, core = series(args.epochs, args.core)
    s = dict(SETTINGS, weights="gaussian", space_time_ratio=1.0, orientation=[0.0, 0.0, 1.0])
    extended = args.fallback != "none" or args.window_breaks != "none"
    if extended:
        s.update(fallback=args.fallback, breaks=args.window_breaks)
    t0 = time.perf_counter()
    pool = facade.tam3c2_pool(clouds, hours / 24.0)
    print(f"epochs {args.epochs}, core points {args.core}, {sum(len(c) for c in clouds)} points in all; "
          f"pool indexed in {time.perf_counter() - t0:.1f} s", flush=True)
    targets = list(range(1, len(clouds)))
    ours = {}
    for threads in args.threads:
        wall = cpu = 0.0
        computed = 0
        for begin in range(0, len(core), args.block):
            t0, c0 = time.perf_counter(), time.process_time()
            block = core[begin:begin + args.block]
            epochwise = stand_in_m3c2(hours, len(block), begin) if extended else None
            r = facade.tam3c2(pool, block, 0, targets, s, threads=threads,
                              **({"epochwise": epochwise} if extended else {}))
            wall, cpu = wall + time.perf_counter() - t0, cpu + time.process_time() - c0
            computed += int(np.isfinite(r["distance"]).sum())
            del r
            print(f"  {threads} thread(s): {min(begin + args.block, len(core))} / {len(core)} core points, "
                  f"{wall:.1f} s wall", flush=True)
        ours[threads] = (wall, cpu)
        print(f"ours, {threads} thread(s): {wall:.2f} s wall, {cpu:.2f} s CPU, {computed} of "
              f"{len(core) * len(targets)} distances", flush=True)
    if args.python and args.tam3c2 and 1 in ours:
        with tempfile.TemporaryDirectory() as tmp:  # py4dgeo writes its py4dgeo.log into the working directory
            out = subprocess.run([args.python, os.path.abspath(__file__), "--reference-side", "--tam3c2",
                                  os.path.abspath(args.tam3c2), "--epochs", str(args.epochs), "--core", str(args.core),
                                  "--reference-core", str(args.reference_core)],
                                 check=True, capture_output=True, text=True, cwd=tmp)
        ref = json.loads(out.stdout.strip().splitlines()[-1])
        scaled = ref["cpu_s"] / ref["core"] * args.core
        print(f"reference, 1 thread: {ref['cpu_s']:.2f} s CPU on {ref['core']} core points, "
              f"{scaled:.1f} s scaled to {args.core}: ours {scaled / ours[1][1]:.0f}x faster in CPU time")
    return 0


if __name__ == "__main__":
    sys.exit(main())
