"""m3c2 series against py4dgeo's SpatiotemporalAnalysis (add epochs, then 4D objects-by-change),
same threads, each tool in its own process (so that its peak resident memory is its own).

    python bench/series_py4dgeo.py [--epochs 100] [--points 1000000] [--core 100000] [--threads 2]
        [--tools m3c2,py4dgeo] [--work DIR]

The epochs are validation/series_synthetic.py's scenario (a rough surface, a landslide,
accumulation piles, noise, one offset epoch) at the requested size, written once as .npy; the
core points are every k-th reference point. m3c2: `m3c2 series REF EPOCH... -o STORE --core CORE`
then `m3c2 series objects --dtw py4dgeo` (py4dgeo's rule, the same work); py4dgeo: SpatiotemporalAnalysis with its M3C2 (the same D, d, L),
each epoch added as it arrives (add_epochs per epoch, as a monitoring system adds them), then
RegionGrowingAlgorithm with the same 4D-OBC parameters. Printed: per-phase wall and CPU time
(user + sys of all the process's threads: the figure to compare on a shared machine), the store's
and the archive's size, each process's peak resident memory (VmHWM) and the largest epoch's size."""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "validation"))
import series_synthetic as ss  # noqa: E402

D, d, L = 1.0, 1.0, 1.0
OBC = dict(neighborhood_radius=1.0, window_width=24, minperiod=24, min_segments=20)


def scenario(points: int, epochs: int) -> ss.Scenario:
    s = ss.Scenario()
    return ss.Scenario(extent=s.extent, density=points / s.extent ** 2, epochs=epochs)


def prepare(work: Path, points: int, epochs: int, core: int) -> dict:
    meta = work / "inputs.json"
    want = {"points": points, "epochs": epochs, "core": core}
    if meta.exists() and json.loads(meta.read_text()) == want:
        return want
    s = scenario(points, epochs)
    paths = ss.write(s, work / "epochs")
    ref = np.load(paths[0])
    step = max(1, len(ref) // core)
    np.save(work / "core.npy", ref[::step][:core])
    meta.write_text(json.dumps(want))
    return want


def cpu() -> float:
    """CPU seconds (user + sys, all threads) of this process so far: on a shared machine the
    figure to compare, wall time counts the other processes' load."""
    t = os.times()
    return t.user + t.system


def peak_kb() -> int:
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1])
    return -1


def run_m3c2(work: Path, threads: int) -> dict:
    from m3c2kit.cli.main import main
    import xarray, zarr  # noqa: F401,E401 - imported before the clock, as py4dgeo is (~2 s CPU)
    epochs = sorted((work / "epochs").glob("epoch_*.npy"))
    store = work / "m3c2.zarr"
    shutil.rmtree(store, ignore_errors=True)
    t0, c0 = time.perf_counter(), cpu()
    assert main(["series", str(epochs[0]), *map(str, epochs), "-o", str(store), "--core", str(work / "core.npy"),
                 "--normal-scale", str(D), "--projection-scale", str(d), "--max-depth", str(L), "--threads",
                 str(threads), "--quiet"]) == 0
    t1, c1 = time.perf_counter(), cpu()
    assert main(["series", "objects", str(store), "-o", str(work / "m3c2_objects.csv"), "--dtw", "py4dgeo",
                 "--neighbourhood-radius", str(OBC["neighborhood_radius"]), "--min-segments",
                 str(OBC["min_segments"]), "--threads", str(threads), "--quiet"]) == 0
    t2, c2 = time.perf_counter(), cpu()
    n_obj = sum(1 for _ in open(work / "m3c2_objects.csv")) - 1
    size = sum(f.stat().st_size for f in store.rglob("*") if f.is_file())
    return {"add": t1 - t0, "obc": t2 - t1, "add_cpu": c1 - c0, "obc_cpu": c2 - c1, "objects": n_obj, "bytes": size,
            "peak_kb": peak_kb()}


def run_py4dgeo(work: Path, threads: int) -> dict:
    import datetime as dt
    import logging
    import py4dgeo
    logging.getLogger("py4dgeo").setLevel(logging.WARNING)
    py4dgeo.set_num_threads(threads)
    epochs = sorted((work / "epochs").glob("epoch_*.npy"))
    archive = work / "py4dgeo.zip"
    archive.unlink(missing_ok=True)
    t0, c0 = time.perf_counter(), cpu()
    start = dt.datetime(2024, 1, 1)
    analysis = py4dgeo.SpatiotemporalAnalysis(str(archive), force=True)
    analysis.reference_epoch = py4dgeo.Epoch(np.load(epochs[0]), timestamp=start)
    analysis.corepoints = np.load(work / "core.npy")
    analysis.m3c2 = py4dgeo.M3C2(cyl_radius=d / 2, normal_radii=(D / 2,), max_distance=L)
    for k, p in enumerate(epochs):
        analysis.add_epochs(py4dgeo.Epoch(np.load(p), timestamp=start + dt.timedelta(hours=k)))
    t1, c1 = time.perf_counter(), cpu()
    algo = py4dgeo.RegionGrowingAlgorithm(neighborhood_radius=OBC["neighborhood_radius"],
                                          window_width=OBC["window_width"], minperiod=OBC["minperiod"],
                                          min_segments=OBC["min_segments"])
    objs = algo.run(analysis)
    t2, c2 = time.perf_counter(), cpu()
    return {"add": t1 - t0, "obc": t2 - t1, "add_cpu": c1 - c0, "obc_cpu": c2 - c1, "objects": len(objs),
            "bytes": archive.stat().st_size, "peak_kb": peak_kb()}


def child(tool: str, work: Path, threads: int) -> dict:
    out = subprocess.run([sys.executable, __file__, "--child", tool, "--work", str(work), "--threads", str(threads)],
                         capture_output=True, text=True, env=dict(os.environ, OMP_NUM_THREADS=str(threads)))
    if out.returncode != 0:
        raise SystemExit(f"{tool} failed:\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--epochs", type=int, default=100)
    ap.add_argument("--points", type=int, default=1_000_000)
    ap.add_argument("--core", type=int, default=100_000)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--tools", default="m3c2,py4dgeo")
    ap.add_argument("--work", type=Path, default=Path("/tmp/m3c2-series-bench"))
    ap.add_argument("--child")
    args = ap.parse_args()
    if args.child:
        fn = run_m3c2 if args.child == "m3c2" else run_py4dgeo
        print(json.dumps(fn(args.work, args.threads)))
        return
    args.work.mkdir(parents=True, exist_ok=True)
    t = time.perf_counter()
    inputs = prepare(args.work, args.points, args.epochs, args.core)
    epoch_bytes = max(f.stat().st_size for f in (args.work / "epochs").glob("epoch_*.npy"))
    print(f"inputs: {inputs['epochs']} epochs of {inputs['points']} points, {inputs['core']} core points, "
          f"{args.threads} threads (made in {time.perf_counter() - t:.0f} s); largest epoch {epoch_bytes / 2**20:.1f} MiB")
    load_before = os.getloadavg()[0]
    results = {tool: child(tool, args.work, args.threads) for tool in args.tools.split(",")}
    print(f"load average before the runs: {load_before:.2f}")
    print(f"{'tool':8} {'add wall s':>10} {'add CPU s':>9} {'OBC wall s':>10} {'OBC CPU s':>9} {'total CPU s':>11} "
          f"{'objects':>7} {'store MiB':>10} {'peak MiB':>9}")
    for tool, r in results.items():
        print(f"{tool:8} {r['add']:10.1f} {r['add_cpu']:9.1f} {r['obc']:10.1f} {r['obc_cpu']:9.1f} "
              f"{r['add_cpu'] + r['obc_cpu']:11.1f} {r['objects']:7d} {r['bytes'] / 2**20:10.2f} {r['peak_kb'] / 1024:9.0f}")
    print(f"load average after the runs: {os.getloadavg()[0]:.2f}")
    if len(results) == 2:
        a, b = results["m3c2"], results["py4dgeo"]
        print(f"py4dgeo / m3c2 CPU: add {b['add_cpu'] / a['add_cpu']:.1f}x, 4D-OBC {b['obc_cpu'] / a['obc_cpu']:.1f}x, "
              f"total {(b['add_cpu'] + b['obc_cpu']) / (a['add_cpu'] + a['obc_cpu']):.1f}x; wall: add "
              f"{b['add'] / a['add']:.1f}x, 4D-OBC {b['obc'] / a['obc']:.1f}x, total "
              f"{(b['add'] + b['obc']) / (a['add'] + a['obc']):.1f}x; store {a['bytes'] / b['bytes']:.2f} of the archive")


if __name__ == "__main__":
    main()
