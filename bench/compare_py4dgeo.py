"""m3c2 against py4dgeo, side by side, on the workloads of docs/performance.md.

    python3 -m venv /tmp/benchenv && /tmp/benchenv/bin/pip install py4dgeo scipy 'laspy[lazrs]' .  # bench env only
    /tmp/benchenv/bin/python bench/compare_py4dgeo.py [--workloads W1,W2,...] [--threads 2] [--scale 1]
        [--tools m3c2,py4dgeo] [--no-scaling] [--memory-limit auto|SIZE] [--tile-size S] [--stream-format laz|las]
        [--repeat auto|N]

For each workload the inputs are generated once (fixed seeds) and saved (workloads on the same
inputs share them); then each tool runs in its own process (so that its peak resident memory is
its own): m3c2 with --threads threads, each run followed by one with 1 thread in the same
process (thread scaling, unless --no-scaling: both walls taken in turn, under the same conditions;
W5 and W7 run again with 1 thread in a process of their own), then py4dgeo with --threads
threads; each prints per-phase times. Each tool runs its
whole computation --repeat times in its process and reports the shortest wall time (auto: 5 runs
for workloads under 500k input points, W1, whose ~35 ms run is otherwise at the mercy of the
scheduler; 1 run for the others); the first run's wall is printed beside. The driver prints the
table: phase times, wall time, peak memory (bytes per input point; m3c2's is its first run's own, taken
before any other run, and the peak with the phase re-runs is printed below the table), core points per second, the
ratio py4dgeo wall / m3c2 wall, and the agreement of the results (|Δdistance| and |ΔLOD| <= 1e-6,
excluding core points where py4dgeo hits one of its known defects, decided from the inputs by
validation/common.py's rule); then the thread-scaling table: m3c2's wall time with 1 thread and
with --threads threads, the speed-up (1-thread wall / N-thread wall) and whether both runs gave
the same bits.

W5 and W5mem are the same 10M + 10M-point pair with 2M core points, run two ways by m3c2:

* W5 (out-of-core, the way a user runs a 20M-point pair in bounded memory): the clouds are
  written once as LAZ (or LAS, --stream-format) files and the core points as core.npy; the worker
  runs m3c2kit.run.tiled.run_tiled -- what `m3c2 compare ref.laz cmp.laz --core core.npy -o change.laz
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
    "W7": ("1M + 1M-point rough pair at 100 points/m2 as LAZ files, 100k core points, whole processes "
           "(`m3c2 compare` on the files against a py4dgeo script reading and writing them)", [2.0], 1.0, 1.0,
           "reference"),
    "W8": ("sparse: 1M + 1M-point rough pair at 1 point/m2 (as W1, a few points per normal sphere), "
           "every tenth reference point a core point", [2.0], 1.0, 5.0, "reference"),
}
# The sweep of the normal sphere's population (S<n>: about n reference points within D / 2) on
# W7's surface (100 points/m2), 50,000 core points, d = 1, depth 1: D = 2 sqrt(n / (100 pi)).
SWEEP = (20, 60, 200, 600, 2000, 6000, 20000)
for _n in SWEEP:
    WORKLOADS[f"S{_n}"] = (f"sweep: about {_n} points per normal sphere (W7's surface, 50k core points)",
                           [round(2.0 * float(np.sqrt(_n / (100.0 * np.pi))), 4)], 1.0, 1.0, "reference")
# Workloads that share one set of inputs (generated once per run).
INPUTS = {"W1": "toronto", "W2": "rough1M", "W3": "rough1M", "W4": "rough1M", "W6": "rough1M",
          "W5": "rough10M", "W5mem": "rough10M", "W7": "moderate1M", "W8": "sparse1M",
          **{f"S{n}": "sweep" for n in SWEEP}}
STREAMED = {"W5"}  # run through the out-of-core path (m3c2kit.run.tiled.run_tiled) from files
WHOLE = {"W7"}  # each tool timed as a whole process from LAZ files to a result file
# Per set of inputs: (points per cloud, core points, side of the square in m) at scale 1.
SIZES = {"rough1M": (1_000_000, 100_000, 10.0), "rough10M": (10_000_000, 2_000_000, 10.0 * np.sqrt(10.0)),
         "moderate1M": (1_000_000, 100_000, 100.0), "sparse1M": (1_000_000, 100_000, 1000.0),
         "sweep": (1_000_000, 50_000, 100.0)}
SMALL_INPUT, SMALL_REPEAT = 500_000, 5  # --repeat auto
# The LOD statistic of eq. (1) with z, as py4dgeo computes it at every n: the same work and results
# to compare. m3c2's default (auto: Welch's t where a cylinder holds fewer than 30 points,
# docs/validation.md) differs from py4dgeo by design where cylinders are small (W8: 1-4 points).
PEER_LOD = "z"
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
        files = key in ("rough10M", "moderate1M")  # streamed (W5) or whole-process (W7) inputs
        n, n_core, side = SIZES[key]
        n, n_core = int(n * scale), int(n_core * scale)
        size = side * np.sqrt(scale)  # the density does not change with the scale
        if key == "sparse1M":  # every tenth reference point a core point (W1: every one)
            ref, cmp, core = rough_pair(seed=7, n_points=n, n_core=n, size=size)
            core = core[::10]
        else:
            ref, cmp, core = rough_pair(seed={"moderate1M": 6, "sweep": 8}.get(key, 5), n_points=n, n_core=n_core,
                                        size=size)
        # Core points 0.5 mm above reference points: no cloud point sits on py4dgeo's segment
        # boundary through the core point (its defect a) merely because the core is a cloud point.
        core = core + np.array([0.0, 0.0, 5e-4])
        if files:
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


def save_table(path: Path, table) -> None:
    """The output's COLUMNS that `table` holds (a LAS file without --all-fields holds the compact
    ones: distance, lod, significant, n1, n2, status), for same_bits and the agreement check."""
    table = {k: np.asarray(table[k]) for k in COLUMNS if k in table}
    if "nx" in table:
        table["normal"] = np.column_stack([table["nx"], table["ny"], table["nz"]])
    np.savez(path, **table)


def las_columns(las) -> dict:
    """A LAS result's COLUMNS, those it holds."""
    names = set(las.point_format.dimension_names)
    return {k: np.asarray(las[k]) for k in COLUMNS if k in names}


def run_m3c2(folder: Path, D, d, L, normals: str, threads: int, tag: str, wall_only: bool, repeat: int,
             one_thread_tag: str | None = None) -> dict:
    """`one_thread_tag`: each run with `threads` is followed by one with 1 thread (its result saved
    under that tag), so that both walls of the thread scaling are taken in turn, in one process,
    under the same conditions (separate processes, minutes apart, differed by 20-30 % on a shared
    machine); `wall_1` is the best of those."""
    import m3c2kit
    from m3c2kit import _core

    ref, cmp, core = (np.load(folder / f"{k}.npy") for k in ("ref", "cmp", "core"))
    params = dict(normal_scale=D, projection_scale=d, max_depth=L, min_points=1, lod=PEER_LOD, threads=threads)
    if normals == "vertical":
        params.update(normal_source="vertical")
        del params["normal_scale"]
    walls, cpus, walls_1 = [], [], []
    peak = 0
    for k in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        r = m3c2kit.compare(ref, cmp, core, **params)
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)  # every thread's CPU: what holds on a loaded machine
        if k == 0:
            # The first run's own peak, before any other run holds a second result (issue 19's goal
            # counts the run alone); the peak with the phase re-runs below is kept beside.
            peak = peak_rss_bytes()
        if one_thread_tag:
            t0 = time.perf_counter()
            r1 = m3c2kit.compare(ref, cmp, core, **{**params, "threads": 1})
            walls_1.append(time.perf_counter() - t0)
            save_table(folder / f"m3c2-{one_thread_tag}.npz", r1.columns())
            del r1
    t_index = t_normals = t_projection = float("nan")
    if not wall_only:
        # Phases, measured after the real run: index builds (normals on no core point), normals,
        # and the projection alone (compare with these normals imposed).
        from m3c2kit.settings import build_params
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
        # The projection: compare with these normals imposed, less the same run on one core point
        # (its two index builds, in parallel and without moments, as in the full one).
        ok = np.flatnonzero(np.isfinite(r.normal).all(1))
        imposed = dict(normal_source="core", projection_scale=d, max_depth=L, min_points=1, threads=threads)
        t = time.perf_counter()
        if len(ok) == 0:
            sys.exit(f"{tag}: no core point has a normal: no projection to time")
        m3c2kit.compare(ref, cmp, core[ok[:1]], core_normals=r.normal[ok[:1]], **imposed)
        t_builds = time.perf_counter() - t
        t = time.perf_counter()
        m3c2kit.compare(ref, cmp, core[ok], core_normals=r.normal[ok], **imposed)
        t_projection = time.perf_counter() - t - t_builds
    peak_with_phases = peak_rss_bytes()
    save_table(folder / f"m3c2-{tag}.npz", r.columns())
    return dict(wall=min(walls), first=walls[0], cpu=min(cpus), index=t_index, normals=t_normals,
                projection=t_projection, peak=peak, peak_with_phases=peak_with_phases,
                **({"wall_1": min(walls_1)} if walls_1 else {}))


def run_m3c2_tiled(folder: Path, D, d, L, normals: str, threads: int, tag: str, memory_limit: str,
                   tile_size: float | None, stream_format: str) -> dict:
    """The out-of-core path from files: what `m3c2 compare ref.laz cmp.laz --core core.npy
    -o change.laz --memory-limit SIZE` (or --tile-size S) runs."""
    from m3c2kit.io import read_cloud
    from m3c2kit.run.tiled import TiledOptions, run_tiled

    params = dict(normal_scale=D, projection_scale=d, max_depth=L, min_points=1, lod=PEER_LOD, threads=threads)
    if normals == "vertical":
        params.update(normal_source="vertical")
        del params["normal_scale"]
    output = folder / f"change-{tag}.{stream_format}"
    t0 = time.perf_counter()
    core = read_cloud(folder / "core.npy").xyz  # as the command line reads --core
    tiling = TiledOptions(tile_size=tile_size, memory_limit=None if tile_size else memory_limit)
    rep = run_tiled(str(folder / f"ref.{stream_format}"), str(folder / f"cmp.{stream_format}"), core,
                    output=str(output), tiling=tiling, **params)
    wall = time.perf_counter() - t0
    peak = peak_rss_bytes()
    # Read back after the peak was taken: the checks' memory is not the run's.
    import laspy
    las = laspy.read(output)
    save_table(folder / f"m3c2-{tag}.npz", las_columns(las))
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
    walls, cpus = [], []
    for _ in range(repeat):  # the phases are those of the last run
        t0, c0 = time.perf_counter(), time.process_time()
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
        cpus.append(time.process_time() - c0)
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
    return dict(wall=wall, first=walls[0], cpu=min(cpus), index=t_index, normals=t_normals, projection=t_projection,
                peak=peak)


# W7, whole processes. m3c2: the command line's own entry point (what the `m3c2` script runs),
# its phases timed by wrapping m3c2kit.base.phases.Phases.phase (reading, computing, writing).
M3C2_WHOLE = r"""
import sys, time, json
t0 = time.perf_counter()
import m3c2kit.cli.main, m3c2kit.base.phases
t_import = time.perf_counter() - t0
seconds = {"import": t_import}
original = m3c2kit.base.phases.Phases.phase
import contextlib
@contextlib.contextmanager
def timed(self, name, total=None):
    t = time.perf_counter()
    with original(self, name, total) as step:
        yield step
    seconds[name] = seconds.get(name, 0.0) + time.perf_counter() - t
m3c2kit.base.phases.Phases.phase = timed
rc = m3c2kit.cli.main.main()  # as the `m3c2` script calls it: the arguments from sys.argv
print("PHASES " + json.dumps(seconds), file=sys.stderr)
sys.exit(rc)
"""
# py4dgeo: read the LAZ files (its own reader), M3C2, write the core points with the distance,
# LOD and counts as a LAZ file (laspy, lazrs), each phase timed.
PY4DGEO_WHOLE = r"""
import sys, time, json
t0 = time.perf_counter()
import numpy as np, laspy, py4dgeo, logging
logging.getLogger("py4dgeo").setLevel(logging.WARNING)
seconds = {"import": time.perf_counter() - t0}
ref_path, cmp_path, core_path, out_path, D, d, L, threads = sys.argv[1:9]
py4dgeo.set_num_threads(int(threads))
t = time.perf_counter()
e1, e2 = py4dgeo.read_from_las(ref_path, cmp_path)
core = np.load(core_path)
seconds["reading"] = time.perf_counter() - t
t = time.perf_counter()
alg = py4dgeo.M3C2(epochs=(e1, e2), corepoints=core, normal_radii=[float(D) / 2], cyl_radius=float(d) / 2,
                   max_distance=float(L), registration_error=0.0, robust_aggr=False,
                   orientation_vector=np.array([0.0, 0.0, 1.0]))
dist, unc = alg.run()
seconds["computing"] = time.perf_counter() - t
t = time.perf_counter()
header = laspy.LasHeader(point_format=0, version="1.4")
header.scales = np.full(3, 1e-5)
header.offsets = np.floor(core.min(axis=0))
header.add_extra_dims([laspy.ExtraBytesParams(name=k, type=np.float64) for k in ("distance", "lod")]
                      + [laspy.ExtraBytesParams(name=k, type=np.float64) for k in ("n1", "n2")])
las = laspy.LasData(header)
las.x, las.y, las.z = core[:, 0], core[:, 1], core[:, 2]
las.distance, las.lod = np.asarray(dist, float), np.asarray(unc["lodetection"], float)
las.n1, las.n2 = np.asarray(unc["num_samples1"], float), np.asarray(unc["num_samples2"], float)
las.write(out_path)
seconds["writing"] = time.perf_counter() - t
print("PHASES " + json.dumps(seconds), file=sys.stderr)
"""


def run_whole(tool: str, folder: Path, D, d, L, threads: int, tag: str) -> dict:
    """One whole process of `tool` from the LAZ files to a LAZ result: wall and CPU (user + sys of
    the child, from getrusage) of the process, its own phases, and its result saved for the checks."""
    import resource

    out = folder / f"{tool}-{tag}.laz"
    if tool == "m3c2":
        cmd = [sys.executable, "-c", M3C2_WHOLE, "compare", str(folder / "ref.laz"), str(folder / "cmp.laz"),
               "--core", str(folder / "core.npy"), "-o", str(out), "--normal-scale", str(D[0]),
               "--projection-scale", str(d), "--max-depth", str(L), "--min-points", "1", "--lod", PEER_LOD,
               "--threads", str(threads), "--quiet", "--float64"]  # the default columns at full precision, as py4dgeo's 4: the checks read them
    else:
        cmd = [sys.executable, "-c", PY4DGEO_WHOLE, str(folder / "ref.laz"), str(folder / "cmp.laz"),
               str(folder / "core.npy"), str(out), str(D[0]), str(d), str(L), str(threads)]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        sys.exit(f"{tool} whole process failed:\n{proc.stderr}")
    phases = json.loads(next(line for line in proc.stderr.splitlines() if line.startswith("PHASES "))[7:])
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    peak = after.ru_maxrss * 1024  # the largest child's, in KiB on Linux: this worker's only child
    import laspy
    las = laspy.read(out)
    if tool == "m3c2":
        save_table(folder / f"m3c2-{tag}.npz", las_columns(las))
    else:
        np.savez(folder / f"py4dgeo-{tag}.npz", **{k: np.asarray(las[k], float) for k in ("distance", "lod", "n1", "n2")})
    out.unlink()
    engine = phases.get("indexing, normals, distances", phases.get("computing", float("nan")))
    return dict(wall=wall, cpu=cpu, phases={k: round(v, 3) for k, v in phases.items()}, index=float("nan"),
                normals=float("nan"), projection=float("nan"), engine=engine, peak=peak)


def lower_bound(binary: str, folder: Path, D, d, L, normals: str, threads: int) -> dict:
    """bench/lower_bound_bench on these inputs (docs/performance.md, "Lower bound")."""
    diameter = 0.0 if normals == "vertical" else max(D)
    cmd = [binary, str(folder / "ref.npy"), str(folder / "cmp.npy"), str(folder / "core.npy"), str(diameter),
           str(d), str(L), str(threads), "3"]
    out = subprocess.run(cmd, capture_output=True, text=True)
    if out.returncode != 0:
        sys.exit(f"{binary} failed:\n{out.stderr}")
    return json.loads(out.stdout.strip().splitlines()[-1])


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
    if len(bad) and "normal" not in ours.files:  # W7's LAS output holds the default columns, without the normals
        return f"{agree.mean():.3%} of {len(agree)} ({len(bad)} differ, not classified: no normals in the output)"
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
    differ = [f"{k} (in one run only)" for k in sorted(set(a.files) ^ set(b.files))]
    for k in (k for k in COLUMNS if k in a.files and k in b.files):
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
    if args.workload in WHOLE:
        out = run_whole(args.tool, folder, spec[1], spec[2], spec[3], args.threads, args.tag)
    elif args.tool == "py4dgeo":
        out = run_py4dgeo(folder, *spec[1:], args.threads, args.tag, args.repeat)
    elif args.workload in STREAMED:
        out = run_m3c2_tiled(folder, *spec[1:], args.threads, args.tag, args.memory_limit, args.tile_size,
                             args.stream_format)
    else:
        out = run_m3c2(folder, *spec[1:], args.threads, args.tag, args.wall_only, args.repeat, args.one_thread_tag)
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
    ap.add_argument("--lower-bound", metavar="BINARY",
                    help="bench/lower_bound_bench (built with -DM3C2_BUILD_BENCH=ON): also time the least work on "
                         "every workload and print m3c2's ratio to it")
    ap.add_argument("--plot", type=Path, metavar="PNG",
                    help="plot the sweep's rows (S...): time per core point against the normal sphere's population")
    ap.add_argument("--worker", nargs=2, metavar=("TOOL", "WORKLOAD"), help=argparse.SUPPRESS)
    ap.add_argument("--folder", help=argparse.SUPPRESS)
    ap.add_argument("--tag", help=argparse.SUPPRESS)
    ap.add_argument("--wall-only", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--one-thread-tag", help=argparse.SUPPRESS)
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
    scaling_rows, notes, bound_rows, whole_rows, sweep_rows = [], [], [], [], []
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
            # A whole process (W7) is one run of each tool whatever --repeat says.
            repeat = str(1 if name in WHOLE else args.repeat if args.repeat != "auto" else
                         SMALL_REPEAT if n_in < SMALL_INPUT and name not in STREAMED else 1)
            memory_limit = args.memory_limit
            if memory_limit == "auto":
                memory_limit = str(max(40 * n_in, 512 * 2**20))

            def run(tool: str, threads: int, tag: str, wall_only: bool = False, one_thread_tag: str = "") -> dict:
                cmd = [sys.executable, __file__, "--worker", tool, name, "--folder", str(folder), "--tag", tag,
                       "--threads", str(threads), "--memory-limit", memory_limit, "--repeat", repeat,
                       "--stream-format", args.stream_format]
                if one_thread_tag:
                    cmd += ["--one-thread-tag", one_thread_tag]
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
            if "m3c2" in tools:  # m3c2 first (N threads, with the 1-thread runs), then py4dgeo
                # In memory, the 1-thread runs alternate with the N-thread ones in the same process
                # (run_m3c2); whole processes (W7) and the streamed W5 run again in a process of their own.
                in_turn = scaling and name not in WHOLE and name not in STREAMED
                rows["m3c2"] = run("m3c2", args.threads, tag, one_thread_tag=f"{name}-t1" if in_turn else "")
                if scaling:
                    wall_1 = rows["m3c2"]["wall_1"] if in_turn else run("m3c2", 1, f"{name}-t1", wall_only=True)["wall"]
                    scaling_rows.append((name, wall_1, rows["m3c2"]["wall"], same_bits(folder, f"{name}-t1", tag)))
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
            if all("cpu" in r for r in rows.values()):
                cpu_ratio = (f", py4dgeo / m3c2 {rows['py4dgeo']['cpu'] / rows['m3c2']['cpu']:.1f}x" if both else "")
                print(f"<!-- {name}: CPU s (user + sys, every thread; best run): "
                      + ", ".join(f"{t} {r['cpu']:.3f}" for t, r in rows.items()) + cpu_ratio + " -->", flush=True)
            print(f"<!-- {name}: {desc}; {n_in:,} input points, {n_core:,} core points, D={D}, d={d}, depth={L}"
                  + (f"; ratio against the py4dgeo run of {p4_shared}" if p4_shared else "")
                  + "".join(f"; {t} peak with the phase re-runs {r['peak_with_phases'] / n_in:.0f} B/pt"
                            for t, r in rows.items() if "peak_with_phases" in r)
                  + (f"; wall: best of {repeat} runs in one process, first runs: "
                     + ", ".join(f"{t} {r['first']:.3f} s" for t, r in rows.items()) if repeat != "1" else "")
                  + " -->", flush=True)
            for tool, r in rows.items():
                if "phases" in r and not (tool == "py4dgeo" and p4_shared):
                    whole_rows.append((name, tool, r))
            if name.startswith("S") and both:
                sweep_rows.append((name, rows["m3c2"]["wall"] / n_core, rows["py4dgeo"]["wall"] / n_core))
            if args.lower_bound and "m3c2" in rows:
                lb = lower_bound(args.lower_bound, folder, D, d, L, normals, args.threads)
                ours = rows["m3c2"].get("engine", rows["m3c2"]["wall"])
                # CPU of the computation (W7: the whole process's, not its engine phase alone: no CPU split)
                ours_cpu = rows["m3c2"].get("cpu", float("nan")) if name not in WHOLE else float("nan")
                bound_rows.append((name, lb, ours, ours_cpu))
                if sweep_rows and sweep_rows[-1][0] == name:
                    sweep_rows[-1] += (lb["neighbours_mean"], lb["total_s"] / n_core)
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
        if whole_rows:
            print()
            print("Whole processes (from the LAZ files to a LAZ result; CPU = user + sys of the process):")
            print()
            print("| workload | tool | wall s | CPU s | import s | reading s | computing s | writing s | peak MiB |")
            print("|---|---|---|---|---|---|---|---|---|")
            for name, tool, r in whole_rows:
                ph = r["phases"]
                compute = ph.get("indexing, normals, distances", ph.get("computing", float("nan")))
                print(f"| {name} | {tool} | {r['wall']:.2f} | {r['cpu']:.2f} | {fmt_s(ph.get('import', float('nan')))} | "
                      f"{fmt_s(ph.get('reading', float('nan')))} | {fmt_s(compute)} | "
                      f"{fmt_s(ph.get('writing', float('nan')))} | {r['peak'] / 2**20:.0f} |", flush=True)
        if bound_rows:
            print()
            print(f"Lower bound (bench/lower_bound_bench, {args.threads} threads, best of 3: grid build, then per core "
                  f"point a brute-force gather-and-sum of the exact neighbours and cylinder points, one plane fit); "
                  f"m3c2 s: the computation's wall (W7: the engine phase of the whole process):")
            print()
            print("| workload | neighbours | cylinder points | bound build s | bound normals s | bound cylinders s | "
                  "bound s | m3c2 s | m3c2 / bound | bound CPU s | m3c2 CPU s | m3c2 / bound, CPU |")
            print("|---|---|---|---|---|---|---|---|---|---|---|---|")
            for name, lb, ours, ours_cpu in bound_rows:
                cpu = (f"{lb['cpu_total_s']:.3f} | {ours_cpu:.3f} | {ours_cpu / lb['cpu_total_s']:.1f}x"
                       if ours_cpu == ours_cpu else f"{lb['cpu_total_s']:.3f} | — | —")
                print(f"| {name} | {lb['neighbours_mean']:.0f} | {lb['cylinder_points_mean']:.0f} | {lb['build_s']:.3f} | "
                      f"{lb['normals_s']:.3f} | {lb['cylinders_s']:.3f} | {lb['total_s']:.3f} | {ours:.3f} | "
                      f"{ours / lb['total_s']:.1f}x | {cpu} |", flush=True)
        if args.plot and sweep_rows:
            plot_sweep(args.plot, sweep_rows, args.threads)
            print(f"wrote {args.plot}")
        if scaling_rows:
            print()
            print(f"Thread scaling, m3c2 (1-thread runs alternating with the N-thread ones in one process, W5 and "
                  f"W7 in processes of their own; best of each; speed-up = 1-thread wall / "
                  f"{args.threads}-thread wall; 'results': the two runs' output tables compared bit for bit):")
            print()
            print(f"| workload | wall s, 1 thread | wall s, {args.threads} threads | speed-up | results |")
            print("|---|---|---|---|---|")
            for name, w1, wn, same in scaling_rows:
                print(f"| {name} | {w1:.2f} | {wn:.2f} | {w1 / wn:.2f}x | {same} |", flush=True)
    finally:
        shutil.rmtree(root, ignore_errors=True)


def plot_sweep(path: Path, rows: list, threads: int) -> None:
    """Time per core point against the normal sphere's population, both tools (and the bound)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = [int(r[0][1:]) for r in rows]
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.loglog(n, [r[1] * 1e6 for r in rows], "o-", label="m3c2")
    ax.loglog(n, [r[2] * 1e6 for r in rows], "s-", label="py4dgeo 1.2")
    if all(len(r) > 3 for r in rows):
        ax.loglog(n, [r[4] * 1e6 for r in rows], "^--", label="lower bound (gather-and-sum)")
    ax.set_xlabel("points per normal sphere (nominal)")
    ax.set_ylabel(f"wall time per core point, µs ({threads} threads)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def _installed(name: str) -> bool:
    from importlib.metadata import PackageNotFoundError, version
    try:
        version(name)
        return True
    except PackageNotFoundError:
        return False


if __name__ == "__main__":
    main()
