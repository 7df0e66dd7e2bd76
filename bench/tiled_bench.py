#!/usr/bin/env python3
"""Out-of-core benchmark (docs/scaling.md): a DERIVED survey pair of --points points per cloud,
made by tiling the bundled Toronto pair (data/toronto-ttp, ~90k points each) on a grid of XY
offsets, is compared (1) on one machine with `m3c2 compare --memory-limit` in a subprocess whose
peak resident memory is measured, and (2) on a Dask LocalCluster; both outputs must be identical.

    PYTHONPATH=python python3 bench/tiled_bench.py --points 5e6            # small, ~1-2 minutes
    PYTHONPATH=python python3 bench/tiled_bench.py --points 1e8 --keep     # the 100M-point run

The derived clouds are written as .npy (float64, streamed through a memory map) in --work.
"""
from __future__ import annotations

import argparse
import filecmp
import json
import math
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "python"))

PITCH = (700.0, 800.0)  # offsets between copies: larger than both clouds' extents (506-614 x 737-760 m)
PARAMS = ["--normal-scale", "4,8", "--projection-scale", "4", "--max-depth", "6", "--core-spacing", "5"]


def derive(points: int, work: Path) -> tuple[Path, Path, int]:
    """Writes ref.npy / cmp.npy: copies of TTP_15 / TTP_23 shifted on a grid, file order copy by copy."""
    from m3c2kit.io import read_cloud
    ref = read_cloud(REPO / "data/toronto-ttp/TTP_15.laz").xyz
    cmp_ = read_cloud(REPO / "data/toronto-ttp/TTP_23.laz").xyz
    copies = max(1, math.ceil(points / len(ref)))
    cols = math.ceil(math.sqrt(copies))
    paths = []
    for name, xyz in (("ref", ref), ("cmp", cmp_)):
        path = work / f"{name}-{copies}.npy"
        if not path.exists():
            tmp = work / f".{name}.npy.part"
            out = np.lib.format.open_memmap(tmp, mode="w+", dtype=np.float64, shape=(copies * len(xyz), 3))
            for k in range(copies):
                shift = np.array([(k % cols) * PITCH[0], (k // cols) * PITCH[1], 0.0])
                out[k * len(xyz):(k + 1) * len(xyz)] = xyz + shift
            out.flush()
            del out
            os.replace(tmp, path)
        paths.append(path)
    return paths[0], paths[1], copies


def children_peak_rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024


class TreeSampler(threading.Thread):
    """Peak of the summed RSS of this process and all its descendants (psutil), sampled."""

    def __init__(self, period=0.2):
        super().__init__(daemon=True)
        self.period, self.peak, self.stop_flag = period, 0, False

    def run(self):
        try:
            import psutil
        except ImportError:
            return
        me = psutil.Process()
        while not self.stop_flag:
            total = 0
            for p in [me, *me.children(recursive=True)]:
                try:
                    total += p.memory_info().rss
                except psutil.Error:
                    pass
            self.peak = max(self.peak, total)
            time.sleep(self.period)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", type=float, default=5e6, help="points per cloud (default 5e6; 1e8 for the big run)")
    ap.add_argument("--memory-limit", default="2GB", help="--memory-limit of the one-machine run (default 2GB)")
    ap.add_argument("--workers", type=int, default=2, help="Dask LocalCluster workers (default 2)")
    ap.add_argument("--work", type=Path, help="folder for the derived inputs and outputs (default: a temporary one)")
    ap.add_argument("--keep", action="store_true", help="keep the derived inputs and outputs")
    ap.add_argument("--skip-dask", action="store_true")
    ap.add_argument("--json", type=Path, help="also write the numbers as JSON")
    args = ap.parse_args()

    work = args.work or Path(tempfile.mkdtemp(prefix="m3c2-bench-"))
    work.mkdir(parents=True, exist_ok=True)
    numbers: dict = {"derived_from": "data/toronto-ttp TTP_15/TTP_23 tiled with XY offsets (synthetic layout)"}
    try:
        t0 = time.perf_counter()
        ref, cmp_, copies = derive(int(args.points), work)
        n_ref, n_cmp = copies * 89815, copies * 81515
        numbers.update(copies=copies, reference_points=n_ref, compared_points=n_cmp,
                       derive_s=round(time.perf_counter() - t0, 1))
        print(f"DERIVED pair (not a real survey): {copies} shifted copies of the Toronto pair, "
              f"{n_ref:,} + {n_cmp:,} points, {ref.stat().st_size / 2**30:.2f} + {cmp_.stat().st_size / 2**30:.2f} GiB .npy")

        # 1. one machine, bounded memory, in a subprocess so its peak RSS is its own
        out1 = work / "one-machine.laz"
        cmd = [sys.executable, "-m", "m3c2kit", "compare", str(ref), str(cmp_), "-o", str(out1), *PARAMS,
               "--memory-limit", args.memory_limit]
        env = dict(os.environ, PYTHONPATH=str(REPO / "python"))
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if proc.returncode != 0:
            print(proc.stdout, proc.stderr)
            return 1
        peak = children_peak_rss_mib()
        lines = [l for l in proc.stdout.splitlines() if l.strip()]
        tile_line = next((l for l in lines if "tile size" in l), "")
        tile_size = float(tile_line.rsplit(" ", 1)[-1]) if tile_line else None
        cores = int(next(l for l in lines if l.startswith("wrote")).split(": ")[1].split()[0])
        numbers["one_machine"] = dict(wall_s=round(wall, 1), peak_rss_mib=round(peak), tile_size=tile_size,
                                      core_points=cores, memory_limit=args.memory_limit,
                                      cloud_points_per_s=round((n_ref + n_cmp) / wall),
                                      core_points_per_s=round(cores / wall))
        print(f"one machine (--memory-limit {args.memory_limit}): {wall:.1f} s, peak RSS {peak:.0f} MiB, "
              f"{(n_ref + n_cmp) / wall / 1e6:.2f} M cloud points/s, {cores / wall / 1e3:.1f} k core points/s")
        for l in lines:
            print("   ", l)

        # 2. the same tiles on a Dask LocalCluster
        if not args.skip_dask:
            from distributed import Client, LocalCluster
            from m3c2kit.run.tiled import TiledOptions, run_tiled
            out2 = work / "dask.laz"
            sampler = TreeSampler()
            sampler.start()
            with LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True,
                              dashboard_address=None, silence_logs=50) as cluster, Client(cluster) as client:
                t0 = time.perf_counter()
                rep = run_tiled(ref, cmp_, output=out2, tiling=TiledOptions(client=client, tile_size=tile_size),
                                core_spacing=5, normal_scale="4,8", projection_scale=4, max_depth=6)
                wall = time.perf_counter() - t0
                worker_peaks = client.run(lambda: resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
            sampler.stop_flag = True
            sampler.join()
            same = filecmp.cmp(out1, out2, shallow=False)
            per_worker = rep.core_points / wall / args.workers
            numbers["dask"] = dict(workers=args.workers, wall_s=round(wall, 1), tiles=rep.tiles,
                                   worker_peak_rss_mib=sorted(round(v) for v in worker_peaks.values()),
                                   tree_peak_rss_mib=round(sampler.peak / 2**20) if sampler.peak else None,
                                   core_points_per_s_per_worker=round(per_worker),
                                   cloud_points_per_s_per_worker=round((n_ref + n_cmp) / wall / args.workers),
                                   seconds={k: round(v, 1) for k, v in rep.seconds.items()},
                                   identical_to_one_machine=same)
            print(f"Dask LocalCluster ({args.workers} workers x 1 thread): {wall:.1f} s, {rep.tiles} tiles, "
                  f"{per_worker / 1e3:.1f} k core points/s per worker, worker peak RSS "
                  f"{numbers['dask']['worker_peak_rss_mib']} MiB; output identical to the one-machine run: {same}")
            print(f"    client-side phases (s): {numbers['dask']['seconds']}")
            if not same:
                return 1
        print(json.dumps(numbers, indent=1))
        if args.json:
            args.json.write_text(json.dumps(numbers, indent=1) + "\n")
        return 0
    finally:
        if not args.keep and args.work is None:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
