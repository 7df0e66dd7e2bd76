"""m3c2 against py4dgeo, side by side, on the workloads of docs/performance.md.

    python3 -m venv /tmp/benchenv && /tmp/benchenv/bin/pip install py4dgeo scipy 'laspy[lazrs]' .  # bench env only
    /tmp/benchenv/bin/python bench/compare_py4dgeo.py [--workloads W1,W2,...] [--threads 2] [--scale 1]
        [--tools m3c2,py4dgeo] [--no-scaling] [--memory-limit auto|SIZE] [--tile-size S] [--stream-format laz|las]
        [--repeat auto|N]

For each workload the inputs are generated once (fixed seeds) and saved (workloads on the same
inputs share them); then each tool runs in its own process (so that its peak resident memory is
its own): m3c2 with --threads threads, then (thread scaling, unless --no-scaling) m3c2 again with
1 thread, then py4dgeo with --threads threads; each prints per-phase times. Each tool runs its
whole computation --repeat times in its process and reports the shortest wall time (auto: 5 runs
for workloads under 500k input points, W1, whose ~35 ms run is otherwise at the mercy of the
scheduler; 1 run for the others); the first run's wall is printed beside. The driver prints the
table: phase times, wall time, peak memory (bytes per input point), core points per second, the
ratio py4dgeo wall / m3c2 wall, and the agreement of the results (|Δdistance| and |ΔLOD| <= 1e-6,
excluding core points where py4dgeo hits one of its known defects, decided from the inputs by
validation/common.py's rule); then the thread-scaling table: m3c2's wall time with 1 thread and
with --threads threads, the speed-up (1-thread wall / N-thread wall) and whether both runs gave
the same bits.

W5 and W5mem are the same 10M + 10M-point pair with 2M core points, run two ways by m3c2:

* W5 (out-of-core, the way a user runs a 20M-point pair in bounded memory): the clouds are
  written once as LAZ (or LAS, --stream-format) files and the core points as core.npy; the worker
  runs m3c2kit.tiling.run_tiled -- what `m3c2 compare ref.laz cmp.laz --core core.npy -o change.laz
  --memory-limit SIZE` runs -- which streams the files and never holds the whole clouds, and
  writes the result file. Its wall time covers everything (reading the core points, streaming and
  distributing both clouds into tiles, computing the tiles, merging and writing the output);
  its peak is the worker's VmHWM, measured before the output is read back for the checks.
  --memory-limit auto is 40 B per input point (the goal), at least 512 MiB.
* W5mem (in memory, as W1-W4/W6): the same coordinates (the LAZ files read back by m3c2's reader,
  saved as .npy) loaded into memory and passed to m3c2kit.compare.

When both are run, the driver checks that their results are identical, bit for bit (every output
column but x, y, z, which the LAS format rounds to its scale). py4dgeo has no out-of-core path: it
runs on the in-memory arrays, once for both rows.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
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
    "W5": ("10M + 10M-point rough pair, 2M core points, out-of-core: streamed from files, tiled under a memory "
           "limit (memory and scaling)", [0.5], 0.2, 0.5, "reference"),
    "W5mem": ("W5's inputs, in memory", [0.5], 0.2, 0.5, "reference"),
    "W6": ("W2 with vertical normals (2D mode)", [1.0], 0.2, 0.5, "vertical"),
}
# Workloads that share one set of inputs (generated once per run).
INPUTS = {"W1": "toronto", "W2": "rough1M", "W3": "rough1M", "W4": "rough1M", "W6": "rough1M",
          "W5": "rough10M", "W5mem": "rough10M"}
STREAMED = {"W5"}  # run through the out-of-core path (m3c2kit.tiling.run_tiled) from files
SMALL_INPUT, SMALL_REPEAT = 500_000, 5  # --repeat auto
LAS_SCALE = 1e-5  # W5's files: coordinates quantised to 0.01 mm (the noise is 1 mm)
COLUMNS = ("distance", "lod", "significant", "n1", "n2", "sigma1", "sigma2", "nx", "ny", "nz", "normal_scale",
           "roughness", "status")  # the output table's columns compared between runs (x, y, z left out)


def make_inputs(key: str, folder: Path, scale: float, stream_format: str) -> None:
    """Writes ref.npy, cmp.npy, core.npy for a set of inputs (derived data, fixed seeds); for the
    10M-point pair also ref.<fmt> and cmp.<fmt>, and the .npy are those files read back by m3c2."""
    from common import rough_pair  # validation/common.py

    if key == "toronto":
        import m3c2kit
        ref = m3c2kit.read(REPO / "data/toronto-ttp/TTP_15.laz").xyz
        cmp = m3c2kit.read(REPO / "data/toronto-ttp/TTP_23.laz").xyz
        core = ref.copy()
    else:
        big = key == "rough10M"
        n, n_core = (10_000_000, 2_000_000) if big else (1_000_000, 100_000)
        n, n_core = int(n * scale), int(n_core * scale)
        size = 10.0 * np.sqrt(n / 1_000_000)  # the density of W2: 10,000 points per m²
        ref, cmp, core = rough_pair(seed=5, n_points=n, n_core=n_core, size=size)
        # Core points 0.5 mm above reference points: no cloud point sits on py4dgeo's segment
        # boundary through the core point (its defect a) merely because the core is a cloud point.
        core = core + np.array([0.0, 0.0, 5e-4])
        if big:
            import m3c2kit
            for name in ("ref", "cmp"):
                path = folder / f"{name}.{stream_format}"
                write_las(path, ref if name == "ref" else cmp)
                # The in-memory variant gets exactly the coordinates the streamed one reads.
                xyz = m3c2kit.read(path).xyz
                if name == "ref":
                    ref = xyz
                else:
                    cmp = xyz
    for name, arr in (("ref", ref), ("cmp", cmp), ("core", core)):
        np.save(folder / f"{name}.npy", np.ascontiguousarray(arr, dtype=np.float64))


def write_las(path: Path, xyz: np.ndarray) -> None:
    """A plain point-format-0 LAS/LAZ file (LAZ through laspy's lazrs backend), written in chunks."""
    import laspy

    header = laspy.LasHeader(point_format=0, version="1.2")
    header.scales = np.full(3, LAS_SCALE)
    header.offsets = np.floor(xyz.min(axis=0))
    with laspy.open(path, mode="w", header=header) as writer:
        for start in range(0, len(xyz), 1 << 20):
            part = xyz[start:start + (1 << 20)]
            points = laspy.ScaleAwarePointRecord.zeros(len(part), header=header)
            points.x, points.y, points.z = part[:, 0], part[:, 1], part[:, 2]
            writer.write_points(points)


def peak_rss_bytes() -> int:
    """This process's peak resident memory. VmHWM starts afresh at exec, unlike ru_maxrss, which
    Linux carries over from the forking parent (the driver, holding every input)."""
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) * 1024 for line in f if line.startswith("VmHWM:"))


def save_table(path: Path, table: dict) -> None:
    table = {k: np.asarray(table[k]) for k in COLUMNS}
    table["normal"] = np.column_stack([table["nx"], table["ny"], table["nz"]])
    np.savez(path, **table)


def run_m3c2(folder: Path, D, d, L, normals: str, threads: int, tag: str, wall_only: bool, repeat: int) -> dict:
    import m3c2kit
    from m3c2kit import _core

    ref, cmp, core = (np.load(folder / f"{k}.npy") for k in ("ref", "cmp", "core"))
    params = dict(normal_scale=D, projection_scale=d, max_depth=L, min_points=1, threads=threads)
    if normals == "vertical":
        params.update(normal_source="vertical")
        del params["normal_scale"]
    walls = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        r = m3c2kit.compare(ref, cmp, core, **params)
        walls.append(time.perf_counter() - t0)
    t_index = t_normals = t_projection = float("nan")
    if not wall_only:
        # Phases, measured after the real run: index builds (normals on no core point), normals,
        # and the projection alone (compare with these normals imposed).
        from m3c2kit.api import build_params
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
        m3c2kit.compare(ref, cmp, core[ok], normal_source="core", core_normals=r.normal[ok], projection_scale=d,
                     max_depth=L, min_points=1, threads=threads)
        t_projection = time.perf_counter() - t - t_index
    peak = peak_rss_bytes()
    save_table(folder / f"m3c2-{tag}.npz", r.columns())
    return dict(wall=min(walls), first=walls[0], index=t_index, normals=t_normals,
                projection=t_projection, peak=peak)


def run_m3c2_tiled(folder: Path, D, d, L, normals: str, threads: int, tag: str, memory_limit: str,
                   tile_size: float | None, stream_format: str) -> dict:
    """The out-of-core path from files: what `m3c2 compare ref.laz cmp.laz --core core.npy
    -o change.laz --memory-limit SIZE` (or --tile-size S) runs."""
    from m3c2kit.io import read_cloud
    from m3c2kit.tiling import run_tiled

    params = dict(normal_scale=D, projection_scale=d, max_depth=L, min_points=1, threads=threads)
    if normals == "vertical":
        params.update(normal_source="vertical")
        del params["normal_scale"]
    output = folder / f"change-{tag}.{stream_format}"
    t0 = time.perf_counter()
    core = read_cloud(folder / "core.npy").xyz  # as the command line reads --core
    rep = run_tiled(str(folder / f"ref.{stream_format}"), str(folder / f"cmp.{stream_format}"), output=str(output),
                    core=core, tile_size=tile_size, memory_limit=None if tile_size else memory_limit, **params)
    wall = time.perf_counter() - t0
    peak = peak_rss_bytes()
    # Read back after the peak was taken: the checks' memory is not the run's.
    import laspy
    las = laspy.read(output)
    save_table(folder / f"m3c2-{tag}.npz", {k: np.asarray(las[k]) for k in COLUMNS})
    del las
    output.unlink()
    s = rep.seconds
    return dict(wall=wall, index=float("nan"), normals=float("nan"), projection=float("nan"), peak=peak,
                tiled=dict(tiles=rep.tiles, tile_size=rep.tile_size, halo=rep.halo, memory_limit=rep.memory_limit,
                           tile_points_max=rep.tile_points_max, estimated_tile_bytes_max=rep.estimated_tile_bytes_max,
                           seconds={k: round(v, 2) for k, v in s.items()}))


def run_py4dgeo(folder: Path, D, d, L, normals: str, threads: int, tag: str, repeat: int) -> dict:
    import logging

    import py4dgeo

    logging.getLogger("py4dgeo").setLevel(logging.WARNING)
    py4dgeo.set_num_threads(threads)
    ref, cmp, core = (np.load(folder / f"{k}.npy") for k in ("ref", "cmp", "core"))
    walls = []
    for _ in range(repeat):  # the phases are those of the last run
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
        walls.append(time.perf_counter() - t0)
        if len(walls) == 1:
            # The first run's results are checked: py4dgeo 1.2's later runs in the same process
            # differ from it at some core points (W1: 2,617 of 89,815).
            first = (dist, unc)
    dist, unc = first
    wall = min(walls)
    peak = peak_rss_bytes()
    np.savez(folder / f"py4dgeo-{tag}.npz", distance=np.asarray(dist, float),
             lod=np.asarray(unc["lodetection"], float),
             n1=np.asarray(unc["num_samples1"]), n2=np.asarray(unc["num_samples2"]))
    return dict(wall=wall, first=walls[0], index=t_index, normals=t_normals, projection=t_projection, peak=peak)


def agreement(folder: Path, ours_tag: str, theirs_tag: str, D, d, L, normals: str) -> str:
    """Share of core points within 1e-6 (our LOD rescaled to py4dgeo's 1.96), over the core
    points that py4dgeo's known defects do not affect (multi-scale: its neighbours are re-counted,
    defect c, so its normals differ by design and no agreement is claimed)."""
    from common import PY4DGEO_Z, Z95, py4dgeo_defect_flags

    ours, theirs = np.load(folder / f"m3c2-{ours_tag}.npz"), np.load(folder / f"py4dgeo-{theirs_tag}.npz")
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


def same_bits(folder: Path, tag_a: str, tag_b: str) -> str:
    """Whether two m3c2 runs gave the same output table, bit for bit (x, y, z left out)."""
    a, b = np.load(folder / f"m3c2-{tag_a}.npz"), np.load(folder / f"m3c2-{tag_b}.npz")
    differ = []
    for k in COLUMNS:
        x, y = np.ascontiguousarray(a[k]), np.ascontiguousarray(b[k])
        if x.shape != y.shape:
            differ.append(f"{k} (shape {x.shape} vs {y.shape})")
            continue
        x, y = x.astype(np.result_type(x, y)), y.astype(np.result_type(x, y))
        if x.tobytes() != y.tobytes():
            n = int((x.view(np.uint8).reshape(len(x), -1) != y.view(np.uint8).reshape(len(y), -1)).any(1).sum())
            differ.append(f"{k} ({n} rows)")
    return "identical bits" if not differ else "DIFFER: " + ", ".join(differ)


def worker(args) -> None:
    spec = WORKLOADS[args.workload]
    folder = Path(args.folder)
    if args.tool == "py4dgeo":
        out = run_py4dgeo(folder, *spec[1:], args.threads, args.tag, args.repeat)
    elif args.workload in STREAMED:
        out = run_m3c2_tiled(folder, *spec[1:], args.threads, args.tag, args.memory_limit, args.tile_size,
                             args.stream_format)
    else:
        out = run_m3c2(folder, *spec[1:], args.threads, args.tag, args.wall_only, args.repeat)
    print(json.dumps(out))


def machine() -> str:
    cpu = "unknown CPU"
    try:
        cpu = next(line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return f"{cpu}, {os.cpu_count()} logical CPUs, {platform.system()} {platform.release()}, Python {platform.python_version()}"


def fmt_s(x: float) -> str:
    return "—" if x != x else f"{x:.2f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workloads", default="W1,W2,W3,W4,W6", help=f"comma-separated, of {','.join(WORKLOADS)}")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--scale", type=float, default=1.0, help="scale the synthetic point counts (quick runs)")
    ap.add_argument("--tools", default="m3c2,py4dgeo")
    ap.add_argument("--scaling", action=argparse.BooleanOptionalAction, default=True,
                    help="also run m3c2 with 1 thread and print the thread-scaling table (default: on)")
    ap.add_argument("--memory-limit", default="auto",
                    help="W5 (out-of-core): the memory limit given to m3c2's tiling, e.g. 800MB; auto: 40 B per "
                         "input point, at least 512 MiB")
    ap.add_argument("--tile-size", type=float, help="W5 (out-of-core): a fixed tile side instead of --memory-limit")
    ap.add_argument("--stream-format", choices=("laz", "las"), default="laz",
                    help="W5 (out-of-core): the format of the input and output files (default laz)")
    ap.add_argument("--repeat", default="auto",
                    help="runs of each tool's whole computation in its process, the shortest wall reported; auto: "
                         f"{SMALL_REPEAT} for workloads of fewer than {SMALL_INPUT:,} input points (W1: a single "
                         "run of ~35 ms is at the mercy of the scheduler), else 1")
    ap.add_argument("--worker", nargs=2, metavar=("TOOL", "WORKLOAD"), help=argparse.SUPPRESS)
    ap.add_argument("--folder", help=argparse.SUPPRESS)
    ap.add_argument("--tag", help=argparse.SUPPRESS)
    ap.add_argument("--wall-only", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        args.tool, args.workload = args.worker
        args.repeat = int(args.repeat)
        return worker(args)

    names = args.workloads.split(",")
    unknown = [n for n in names if n not in WORKLOADS]
    if unknown:
        ap.error(f"unknown workload(s) {', '.join(unknown)}; known: {', '.join(WORKLOADS)}")
    tools = args.tools.split(",")
    from importlib.metadata import version
    if "py4dgeo" in tools:
        import py4dgeo  # noqa: F401  (fail early outside the bench environment)
    scaling = args.scaling and "m3c2" in tools and args.threads != 1
    print(f"machine: {machine()}")
    print(f"m3c2 {version('m3c2') if _installed('m3c2') else '(source tree)'}, "
          f"py4dgeo {version('py4dgeo') if _installed('py4dgeo') else '(not installed)'}, "
          f"threads {args.threads} for both, synthetic scale {args.scale}")
    header = ("workload", "tool", "index s", "normals s", "projection s", "wall s", "peak B/pt", "core pts/s")
    print("| " + " | ".join(header) + " | ratio | agreement |")
    print("|" + "---|" * (len(header) + 2))
    last_use = {INPUTS[n]: i for i, n in enumerate(names)}
    root = Path(tempfile.mkdtemp(prefix="m3c2-bench-"))
    folders: dict[str, Path] = {}
    py4dgeo_rows: dict[tuple, tuple[str, dict]] = {}  # (inputs, parameters) -> (workload, row): run once
    scaling_rows, notes = [], []
    try:
        for i, name in enumerate(names):
            desc, D, d, L, normals = WORKLOADS[name]
            key = INPUTS[name]
            if key not in folders:
                folders[key] = root / key
                folders[key].mkdir()
                make_inputs(key, folders[key], args.scale, args.stream_format)
            folder = folders[key]
            n_in = sum(len(np.load(folder / f"{k}.npy", mmap_mode="r")) for k in ("ref", "cmp"))
            n_core = len(np.load(folder / "core.npy", mmap_mode="r"))
            repeat = str(args.repeat if args.repeat != "auto" else
                         SMALL_REPEAT if n_in < SMALL_INPUT and name not in STREAMED else 1)
            memory_limit = args.memory_limit
            if memory_limit == "auto":
                memory_limit = str(max(40 * n_in, 512 * 2**20))

            def run(tool: str, threads: int, tag: str, wall_only: bool = False) -> dict:
                cmd = [sys.executable, __file__, "--worker", tool, name, "--folder", str(folder), "--tag", tag,
                       "--threads", str(threads), "--memory-limit", memory_limit, "--repeat", repeat,
                       "--stream-format", args.stream_format]
                if args.tile_size:
                    cmd += ["--tile-size", str(args.tile_size)]
                if wall_only:
                    cmd.append("--wall-only")
                out = subprocess.run(cmd, capture_output=True, text=True)
                if out.returncode != 0:
                    sys.exit(f"{tool} on {name} ({threads} threads) failed:\n{out.stderr}")
                return json.loads(out.stdout.strip().splitlines()[-1])

            rows = {}
            tag = f"{name}-t{args.threads}"
            if "m3c2" in tools:  # m3c2 first (N threads, then 1 thread), then py4dgeo
                rows["m3c2"] = run("m3c2", args.threads, tag)
                if scaling:
                    one = run("m3c2", 1, f"{name}-t1", wall_only=True)
                    scaling_rows.append((name, one["wall"], rows["m3c2"]["wall"], same_bits(folder, f"{name}-t1", tag)))
            p4_key = (key, tuple(D), d, L, normals)
            p4_shared = None
            if "py4dgeo" in tools:
                if p4_key in py4dgeo_rows:  # W5 and W5mem: one py4dgeo run (in memory) for both
                    p4_shared, rows["py4dgeo"] = py4dgeo_rows[p4_key]
                else:
                    rows["py4dgeo"] = run("py4dgeo", args.threads, name)
                    py4dgeo_rows[p4_key] = (name, rows["py4dgeo"])
            both = "m3c2" in rows and "py4dgeo" in rows
            ratio = (rows["py4dgeo"]["wall"] / rows["m3c2"]["wall"]) if both else float("nan")
            agree = agreement(folder, tag, p4_shared or name, D, d, L, normals) if both else ""
            for tool, r in rows.items():
                if tool == "py4dgeo" and p4_shared:
                    continue  # printed with p4_shared's row
                print(f"| {name} | {tool} | {fmt_s(r['index'])} | {fmt_s(r['normals'])} | {fmt_s(r['projection'])} | "
                      f"{r['wall']:.2f} | {r['peak'] / n_in:.0f} ({r['peak'] / 2**20:.0f} MiB) | {n_core / r['wall']:,.0f} | "
                      f"{f'{ratio:.1f}x' if tool == 'm3c2' and ratio == ratio else ''} | {agree if tool == 'm3c2' else ''} |",
                      flush=True)
            print(f"<!-- {name}: {desc}; {n_in:,} input points, {n_core:,} core points, D={D}, d={d}, depth={L}"
                  + (f"; ratio against the py4dgeo run of {p4_shared}" if p4_shared else "")
                  + (f"; wall: best of {repeat} runs in one process, first runs: "
                     + ", ".join(f"{t} {r['first']:.3f} s" for t, r in rows.items()) if repeat != "1" else "")
                  + " -->", flush=True)
            tiled = rows.get("m3c2", {}).get("tiled")
            if tiled:
                limit = tiled["memory_limit"]
                print(f"<!-- {name}: out-of-core from {args.stream_format.upper()} files, "
                      + (f"--memory-limit {limit / 2**20:.0f} MiB, " if limit else "")
                      + f"{tiled['tiles']} tiles of {tiled['tile_size']:.4g} (halo {tiled['halo']:.4g}), largest tile "
                      f"{tiled['tile_points_max']:,} cloud points (estimated {tiled['estimated_tile_bytes_max'] / 2**20:.0f} MiB); "
                      f"seconds: {', '.join(f'{k} {v}' for k, v in tiled['seconds'].items())} -->", flush=True)
            # The streamed and in-memory runs of the same inputs must give the same bits.
            for other in names[:i]:
                if INPUTS[other] == key and WORKLOADS[other][1:] == WORKLOADS[name][1:] and "m3c2" in tools:
                    notes.append(f"{other} vs {name} (m3c2, {args.threads} threads): "
                                 f"{same_bits(folder, f'{other}-t{args.threads}', tag)}")
            if last_use[key] == i:
                shutil.rmtree(folder, ignore_errors=True)
        for note in notes:
            print(note, flush=True)
        if scaling_rows:
            print()
            print(f"Thread scaling, m3c2 (each run in its own process, same inputs; speed-up = 1-thread wall / "
                  f"{args.threads}-thread wall; 'results': the two runs' output tables compared bit for bit):")
            print()
            print(f"| workload | wall s, 1 thread | wall s, {args.threads} threads | speed-up | results |")
            print("|---|---|---|---|---|")
            for name, w1, wn, same in scaling_rows:
                print(f"| {name} | {w1:.2f} | {wn:.2f} | {w1 / wn:.2f}x | {same} |", flush=True)
    finally:
        shutil.rmtree(root, ignore_errors=True)


def _installed(name: str) -> bool:
    from importlib.metadata import PackageNotFoundError, version
    try:
        version(name)
        return True
    except PackageNotFoundError:
        return False


if __name__ == "__main__":
    main()
