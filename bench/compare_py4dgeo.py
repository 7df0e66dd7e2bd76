"""m3c2 against py4dgeo, side by side, on the workloads of docs/performance.md.

    python3 -m venv /tmp/benchenv && /tmp/benchenv/bin/pip install py4dgeo scipy . # bench env only
    /tmp/benchenv/bin/python bench/compare_py4dgeo.py [--workloads W1,W2,...] [--threads 2] [--repeat 1]

For each workload the inputs are generated once (fixed seeds) and saved; then each tool runs in
its own process (so that its peak resident memory is its own), alternating m3c2 and py4dgeo, and
prints per-phase times. The driver prints the table: phase times, wall time, peak memory (bytes
per input point), core points per second, the ratio m3c2 / py4dgeo, and the agreement of the
results (|Δdistance| and |ΔLOD| <= 1e-6, excluding core points where py4dgeo hits one of its known
defects, decided from the inputs by validation/common.py's rule).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "validation"))

# name: (description, D list, d, depth, normals) -- D and d are diameters; py4dgeo gets radii.
WORKLOADS = {
    "W1": ("real: Toronto pair, every reference point a core point", [2.0], 1.0, 5.0, "reference"),
    "W2": ("1M-point rough pair, 100k core points", [1.0], 0.2, 0.5, "reference"),
    "W3": ("W2 with multi-scale normals, D = 0.5..2.5 (5 scales)", [0.5, 1.0, 1.5, 2.0, 2.5], 0.2, 0.5, "reference"),
    "W4": ("W2 with long cylinders: depth 10", [1.0], 0.2, 10.0, "reference"),
    "W5": ("10M + 10M-point rough pair, 2M core points (memory and scaling)", [0.5], 0.2, 0.5, "reference"),
    "W6": ("W2 with vertical normals (2D mode)", [1.0], 0.2, 0.5, "vertical"),
}


def make_inputs(name: str, folder: Path, scale: float) -> None:
    """Writes ref.npy, cmp.npy, core.npy for a workload (derived data, fixed seeds)."""
    from common import rough_pair  # validation/common.py

    if name == "W1":
        import m3c2
        ref = m3c2.read(REPO / "data/toronto-ttp/TTP_15.laz").xyz
        cmp = m3c2.read(REPO / "data/toronto-ttp/TTP_23.laz").xyz
        core = ref.copy()
    else:
        big = name == "W5"
        n, n_core = (10_000_000, 2_000_000) if big else (1_000_000, 100_000)
        n, n_core = int(n * scale), int(n_core * scale)
        size = 10.0 * np.sqrt(n / 1_000_000)  # the density of W2: 10,000 points per m²
        ref, cmp, core = rough_pair(seed=5, n_points=n, n_core=n_core, size=size)
        # Core points 0.5 mm above reference points: no cloud point sits on py4dgeo's segment
        # boundary through the core point (its defect a) merely because the core is a cloud point.
        core = core + np.array([0.0, 0.0, 5e-4])
    for key, arr in (("ref", ref), ("cmp", cmp), ("core", core)):
        np.save(folder / f"{key}.npy", np.ascontiguousarray(arr, dtype=np.float64))


def peak_rss_bytes() -> int:
    """This process's peak resident memory. VmHWM starts afresh at exec, unlike ru_maxrss, which
    Linux carries over from the forking parent (the driver, holding every input)."""
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) * 1024 for line in f if line.startswith("VmHWM:"))


def run_m3c2(folder: Path, D, d, L, normals: str, threads: int) -> dict:
    import m3c2
    from m3c2 import _core

    ref, cmp, core = (np.load(folder / f"{k}.npy") for k in ("ref", "cmp", "core"))
    params = dict(normal_scale=D, projection_scale=d, max_depth=L, min_points=1, threads=threads)
    if normals == "vertical":
        params.update(normal_source="vertical")
        del params["normal_scale"]
    t0 = time.perf_counter()
    r = m3c2.compare(ref, cmp, core, **params)
    wall = time.perf_counter() - t0
    # Phases, measured after the real run: index builds (normals on no core point), normals,
    # and the projection alone (compare with these normals imposed).
    from m3c2.api import build_params
    empty = np.empty((0, 3))
    p = build_params(normal_scale=D, projection_scale=d, max_depth=L)
    t = time.perf_counter(); _core.compute_normals(ref, empty, p, threads=threads)
    t_ref = time.perf_counter() - t
    t = time.perf_counter(); _core.compute_normals(cmp, empty, p, threads=threads)
    t_index = t_ref + time.perf_counter() - t
    t_normals = 0.0
    if normals != "vertical":
        t = time.perf_counter(); _core.compute_normals(ref, core, p, threads=threads)
        t_normals = time.perf_counter() - t - t_ref
    ok = np.isfinite(r.normal).all(1)
    t = time.perf_counter()
    m3c2.compare(ref, cmp, core[ok], normal_source="core", core_normals=r.normal[ok], projection_scale=d,
                 max_depth=L, min_points=1, threads=threads)
    t_projection = time.perf_counter() - t - t_index
    np.savez(folder / "m3c2.npz", distance=r.distance, lod=r.lod, normal=r.normal, n1=r.n1, n2=r.n2)
    return dict(wall=wall, index=t_index, normals=t_normals, projection=t_projection, peak=peak_rss_bytes())


def run_py4dgeo(folder: Path, D, d, L, normals: str, threads: int) -> dict:
    import logging

    import py4dgeo

    logging.getLogger("py4dgeo").setLevel(logging.WARNING)
    py4dgeo.set_num_threads(threads)
    ref, cmp, core = (np.load(folder / f"{k}.npy") for k in ("ref", "cmp", "core"))
    t0 = time.perf_counter()
    e1, e2 = py4dgeo.Epoch(ref), py4dgeo.Epoch(cmp)
    e1.build_kdtree()
    e2.build_kdtree()
    t_index = time.perf_counter() - t0
    kw = {}
    if normals == "vertical":
        kw["corepoint_normals"] = np.tile([0.0, 0.0, 1.0], (len(core), 1))
    alg = py4dgeo.M3C2(epochs=(e1, e2), corepoints=core, normal_radii=[x / 2 for x in D], cyl_radius=d / 2,
                       max_distance=L, registration_error=0.0, robust_aggr=False,
                       orientation_vector=np.array([0.0, 0.0, 1.0]), **kw)
    t = time.perf_counter()
    alg.directions()
    t_normals = time.perf_counter() - t if normals != "vertical" else 0.0
    t = time.perf_counter()
    dist, unc = alg.run()
    t_projection = time.perf_counter() - t
    wall = time.perf_counter() - t0
    np.savez(folder / "py4dgeo.npz", distance=np.asarray(dist, float), lod=np.asarray(unc["lodetection"], float),
             n1=np.asarray(unc["num_samples1"]), n2=np.asarray(unc["num_samples2"]))
    return dict(wall=wall, index=t_index, normals=t_normals, projection=t_projection, peak=peak_rss_bytes())


def agreement(folder: Path, D, d, L, normals: str) -> str:
    """Share of core points within 1e-6 (our LOD rescaled to py4dgeo's 1.96), over the core
    points that py4dgeo's known defects do not affect (multi-scale: its neighbours are re-counted,
    defect c, so its normals differ by design and no agreement is claimed)."""
    from common import PY4DGEO_Z, Z95, py4dgeo_defect_flags

    ours, theirs = np.load(folder / "m3c2.npz"), np.load(folder / "py4dgeo.npz")
    if len(D) > 1:
        return "n/a (py4dgeo multi-scale defect c)"
    lod = ours["lod"] * PY4DGEO_Z / Z95
    close = lambda a, b: (np.abs(a - b) <= 1e-6) | (np.isnan(a) & np.isnan(b))  # noqa: E731
    agree = close(ours["distance"], theirs["distance"]) & close(lod, theirs["lod"])
    bad = np.flatnonzero(~agree)
    flagged = 0
    if len(bad) and normals != "vertical":
        ref, cmp, core = (np.load(folder / f"{k}.npy") for k in ("ref", "cmp", "core"))
        flags = py4dgeo_defect_flags(ref, cmp, core, ours["normal"], D[0], d, L, which=bad[:20000])
        flagged = int((flags[bad] != 0).sum())
        if len(bad) > 20000:
            return f"{agree.mean():.2%} raw; {len(bad)} differ (too many to classify)"
    considered = len(agree) - flagged
    return f"{agree.sum() / considered:.3%} of {considered} ({flagged} py4dgeo-defect points excluded)"


def worker(args) -> None:
    spec = WORKLOADS[args.workload]
    fn = run_m3c2 if args.tool == "m3c2" else run_py4dgeo
    print(json.dumps(fn(Path(args.folder), spec[1], spec[2], spec[3], spec[4], args.threads)))


def machine() -> str:
    cpu = "unknown CPU"
    try:
        cpu = next(line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return f"{cpu}, {os.cpu_count()} logical CPUs, {platform.system()} {platform.release()}, Python {platform.python_version()}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workloads", default="W1,W2,W3,W4,W6")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--scale", type=float, default=1.0, help="scale the synthetic point counts (quick runs)")
    ap.add_argument("--tools", default="m3c2,py4dgeo")
    ap.add_argument("--worker", nargs=2, metavar=("TOOL", "WORKLOAD"))
    ap.add_argument("--folder")
    args = ap.parse_args()
    if args.worker:
        args.tool, args.workload = args.worker
        return worker(args)

    import py4dgeo  # noqa: F401  (fail early outside the bench environment)
    from importlib.metadata import version
    print(f"machine: {machine()}")
    print(f"m3c2 {version('m3c2') if _installed('m3c2') else '(source tree)'}, py4dgeo {version('py4dgeo')}, "
          f"threads {args.threads} for both, synthetic scale {args.scale}")
    header = ("workload", "tool", "index s", "normals s", "projection s", "wall s", "peak B/pt", "core pts/s")
    print("| " + " | ".join(header) + " | ratio | agreement |")
    print("|" + "---|" * (len(header) + 2))
    for name in args.workloads.split(","):
        desc, D, d, L, normals = WORKLOADS[name]
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp)
            make_inputs(name, folder, args.scale)
            n_in = sum(len(np.load(folder / f"{k}.npy", mmap_mode="r")) for k in ("ref", "cmp"))
            n_core = len(np.load(folder / "core.npy", mmap_mode="r"))
            rows = {}
            for tool in args.tools.split(","):  # m3c2 first, then py4dgeo: alternating per workload
                out = subprocess.run([sys.executable, __file__, "--worker", tool, name, "--folder", tmp,
                                      "--threads", str(args.threads)], capture_output=True, text=True, check=True)
                rows[tool] = json.loads(out.stdout.strip().splitlines()[-1])
            ratio = (rows["py4dgeo"]["wall"] / rows["m3c2"]["wall"]) if len(rows) == 2 else float("nan")
            agree = agreement(folder, D, d, L, normals) if len(rows) == 2 else ""
            for tool, r in rows.items():
                print(f"| {name} | {tool} | {r['index']:.2f} | {r['normals']:.2f} | {r['projection']:.2f} | "
                      f"{r['wall']:.2f} | {r['peak'] / n_in:.0f} ({r['peak'] / 2**20:.0f} MiB) | {n_core / r['wall']:,.0f} | "
                      f"{f'{ratio:.1f}x' if tool == 'm3c2' and ratio == ratio else ''} | {agree if tool == 'm3c2' else ''} |",
                      flush=True)
            print(f"<!-- {name}: {desc}; {n_in:,} input points, {n_core:,} core points, D={D}, d={d}, depth={L} -->",
                  flush=True)


def _installed(name: str) -> bool:
    from importlib.metadata import PackageNotFoundError, version
    try:
        version(name)
        return True
    except PackageNotFoundError:
        return False


if __name__ == "__main__":
    main()
