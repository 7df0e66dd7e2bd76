"""In-memory peak of an M3C2 run, phase by phase (docs/performance.md, "Memory, byte by byte").

    python bench/memory_bench.py [--points 2e6] [--core 4e5] [--threads 2] [--mode api|cli] [--reorder-inputs]
        [--work DIR]

W5mem's inputs at another size (validation/common.py's rough_pair, seed 5, W5's density: 10M
points on 31.6 m x 31.6 m; D = 0.5, d = 0.2, L = 0.5, normals from the reference), generated
once as ref.npy / cmp.npy / core.npy in --work, then run once in a fresh process:

* --mode api: the arrays loaded with np.load and passed to m3c2kit.compare (what W5mem runs,
  without the benchmark's phase re-runs; with --reorder-inputs, which the arrays it loaded allow,
  the engine orders them in place instead of copying them). A thread samples the process's resident memory every
  2 ms, so that the peak is placed in a phase: before the first progress callback (the index
  builds and the result arrays' set-up), during the core points, or after (the Python Result).
* --mode cli: `m3c2 compare ref.npy cmp.npy --core core.npy -o out.ply` (the command line reads
  the files itself and orders its own arrays in place), its peak from the child's rusage.

Prints one JSON line: the peak (VmHWM) in MiB and in bytes per input point, and for --mode api
the resident memory at each step (after the imports, after loading the inputs, at the end of
the index builds, the highest sample of each phase).
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
PARAMS = dict(normal_scale=[0.5], projection_scale=0.2, max_depth=0.5, min_points=1)
MIB = 1 << 20


def make_inputs(work: Path, points: int, core: int) -> None:
    if all((work / f"{k}.npy").exists() for k in ("ref", "cmp", "core")):
        ref = np.load(work / "ref.npy", mmap_mode="r")
        got_core = np.load(work / "core.npy", mmap_mode="r")
        if len(ref) == points and len(got_core) == core:
            return
    sys.path.insert(0, str(REPO / "validation"))
    from common import rough_pair

    size = 10.0 * np.sqrt(10.0) * np.sqrt(points / 10_000_000)  # W5's density
    ref, cmp, core_xyz = rough_pair(seed=5, n_points=points, n_core=core, size=size)
    core_xyz = core_xyz + np.array([0.0, 0.0, 5e-4])  # as the benchmark: off the cloud points
    for name, arr in (("ref", ref), ("cmp", cmp), ("core", core_xyz)):
        np.save(work / f"{name}.npy", np.ascontiguousarray(arr, dtype=np.float64))


def rss() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def hwm() -> int:
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) * 1024 for line in f if line.startswith("VmHWM:"))


def child_api(work: Path, threads: int, reorder_inputs: bool) -> dict:
    import m3c2kit

    after_import = rss()
    ref, cmp, core = (np.load(work / f"{k}.npy") for k in ("ref", "cmp", "core"))
    after_load = rss()
    samples: list[tuple[float, int]] = []
    stop = threading.Event()

    def sample():
        while not stop.is_set():
            samples.append((time.perf_counter(), rss()))
            time.sleep(0.002)

    first_progress: list[float] = []

    def progress(done, total):
        if not first_progress:
            first_progress.append(time.perf_counter())
            first_progress.append(rss())

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    t0 = time.perf_counter()
    result = m3c2kit.compare(ref, cmp, core, threads=threads, progress=progress, reorder_inputs=reorder_inputs,
                             **PARAMS)
    t_engine_end = time.perf_counter()
    stop.set()
    sampler.join()
    peak = hwm()
    built = first_progress[0] if first_progress else t_engine_end

    def highest(a, b):
        return max((r for t, r in samples if a <= t < b), default=0)

    n = len(ref) + len(cmp)
    return dict(points=n, core=len(core), threads=threads, reorder_inputs=reorder_inputs, peak_mib=round(peak / MIB, 1),
                peak_bytes_per_point=round(peak / n, 1),
                after_import_mib=round(after_import / MIB, 1), after_load_mib=round(after_load / MIB, 1),
                build_peak_mib=round(highest(t0, built) / MIB, 1),
                at_first_progress_mib=round(first_progress[1] / MIB, 1) if first_progress else None,
                core_points_peak_mib=round(highest(built, t_engine_end) / MIB, 1),
                after_mib=round(rss() / MIB, 1), seconds=round(t_engine_end - t0, 2),
                build_seconds=round(built - t0, 2), valid=int(np.isfinite(result.distance).sum()),
                build_trace_mib=[(round(t - t0, 3), round(r / MIB)) for t, r in samples if t < built][::10])


def run_cli(work: Path, threads: int) -> dict:
    out = work / "out.ply"
    out.unlink(missing_ok=True)
    cmd = [sys.executable, "-m", "m3c2kit", "compare", str(work / "ref.npy"), str(work / "cmp.npy"), "--core",
           str(work / "core.npy"), "-o", str(out), "--normal-scale", "0.5", "--projection-scale", "0.2",
           "--max-depth", "0.5", "--min-points", "1", "--threads", str(threads), "--quiet"]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        sys.exit(f"m3c2 compare failed:\n{proc.stderr}")
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024
    n = len(np.load(work / "ref.npy", mmap_mode="r")) + len(np.load(work / "cmp.npy", mmap_mode="r"))
    out.unlink(missing_ok=True)
    return dict(points=n, threads=threads, mode="cli", peak_mib=round(peak / MIB, 1),
                peak_bytes_per_point=round(peak / n, 1), seconds=round(wall, 2))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=float, default=2e6, help="points per cloud")
    ap.add_argument("--core", type=float, default=4e5, help="core points")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--mode", choices=("api", "cli"), default="api")
    ap.add_argument("--reorder-inputs", action="store_true", help="--mode api: m3c2kit.compare(reorder_inputs=True)")
    ap.add_argument("--work", type=Path, help="folder of the inputs (kept; default: a temporary one)")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(json.dumps(child_api(args.work, args.threads, args.reorder_inputs)))
        return
    with tempfile.TemporaryDirectory() as tmp:
        work = args.work or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        make_inputs(work, int(args.points), int(args.core))
        if args.mode == "cli":
            print(json.dumps(run_cli(work, args.threads)))
            return
        # A fresh process: its peak is the run's alone, not the generator's.
        proc = subprocess.run([sys.executable, __file__, "--child", "--work", str(work), "--threads",
                               str(args.threads)] + (["--reorder-inputs"] if args.reorder_inputs else []),
                              capture_output=True, text=True)
        if proc.returncode != 0:
            sys.exit(proc.stderr)
        print(proc.stdout.strip().splitlines()[-1])


if __name__ == "__main__":
    main()
