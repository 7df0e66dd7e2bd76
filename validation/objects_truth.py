"""4D objects-by-change against a known truth, ours (each `--dtw` rule) beside py4dgeo 1.2.0 on the
same inputs: the seeded scenes of validation/objects_scenes.py (five events above the noise,
two seeds), raw, smoothed (our `smooth`, a centred median of 5 epochs, given to both tools) and raw
with 5 % of the cells NaN.
Prints per event the best IoU in space and time of an object (members x [start, end] against
footprint x [first changed epoch - 1, last]; found: IoU >= 0.5), recall and precision, then
`--dtw py4dgeo` against py4dgeo's own RegionGrowingAlgorithm: the same seeds in the same order,
and each object's members (docs/series.md, "Analysis"). Then recall and false objects summed over
--more further seeds.

    PYTHONPATH=python python validation/objects_truth.py [--py4dgeo-python /tmp/p4d/bin/python] [--more 20]

py4dgeo runs in its own interpreter (a separate venv: python3 -m venv /tmp/p4d &&
/tmp/p4d/bin/pip install py4dgeo==1.2.0), never beside m3c2kit; without it only ours is printed."""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import objects_scenes as sc  # noqa: E402

SEEDS = (1, 2)
RULES = ("baseline", "seed-start", "py4dgeo")
WINDOW = 5  # the smoothing's epochs


def py4dgeo_child(npz: Path, out: Path) -> None:
    """Runs in py4dgeo's interpreter: its RegionGrowingAlgorithm with its defaults."""
    import datetime as dt
    import logging

    import py4dgeo
    logging.getLogger("py4dgeo").setLevel(logging.WARNING)
    data = np.load(npz)
    analysis = py4dgeo.SpatiotemporalAnalysis(str(npz.with_suffix(".zip")), force=True)
    analysis.corepoints = data["core"]
    analysis.distances = data["distances"]
    analysis.timedeltas = [dt.timedelta(hours=k) for k in range(data["distances"].shape[1])]
    t0 = time.perf_counter()
    objects = py4dgeo.RegionGrowingAlgorithm(neighborhood_radius=1.0).run(analysis)
    seconds = time.perf_counter() - t0
    out.write_text(json.dumps({
        "seconds": seconds, "version": py4dgeo.__version__,
        "seeds": [[s.index, s.start_epoch, s.end_epoch] for s in analysis.seeds],
        "objects": [{"seed": [o.seed.index, o.start_epoch, o.end_epoch], "threshold": o.threshold,
                     "members": {str(k): v for k, v in o._data.indices_distances.items()}} for o in objects]}))


def run_py4dgeo(python: str, core: np.ndarray, d: np.ndarray, folder: Path) -> dict:
    npz = folder / "scene.npz"
    np.savez(npz, core=core, distances=d)
    out = folder / "py4dgeo.json"
    subprocess.run([python, __file__, "--child", str(npz), str(out)], check=True)
    return json.loads(out.read_text())


def gaps(d: np.ndarray, seed: int) -> np.ndarray:
    """5 % of the (core point, epoch) cells NaN: epochs without a distance (py4dgeo interpolates them
    in place in its own array, docs/series.md)."""
    out = d.copy()
    out[np.random.default_rng(seed + 100).random(d.shape) < 0.05] = np.nan
    return out


def run_ours(rule: str, core: np.ndarray, d: np.ndarray) -> dict:
    from m3c2kit.series import engine
    t0 = time.perf_counter()
    out = engine.objects_by_change(d, core, engine.objects_params(dtw=rule))
    out["seconds"] = time.perf_counter() - t0
    return out


def our_objects(out: dict) -> list[dict]:
    offsets = out["member_offsets"]
    return [{"seed": [int(out["object_seed"][k]), int(out["object_start"][k]), int(out["object_end"][k])],
             "threshold": float(out["object_threshold"][k]),
             "members": dict(zip(map(int, out["members"][offsets[k]:offsets[k + 1]]),
                                 map(float, out["member_dtw"][offsets[k]:offsets[k + 1]])))}
            for k in range(len(offsets) - 1)]


def extents(objects: list[dict], n_core: int) -> list[np.ndarray]:
    return [sc.extent(n_core, [int(c) for c in o["members"]], o["seed"][1], o["seed"][2]) for o in objects]


def compare_members(ours: list[dict], theirs: list[dict]) -> list[str]:
    """Objects by seed: equal members, or what differs."""
    lines = []
    mine = {tuple(o["seed"]): o for o in ours}
    for o in theirs:
        key = tuple(o["seed"])
        a = set(mine[key]["members"]) if key in mine else set()
        b = {int(c) for c in o["members"]}
        if key not in mine:
            lines.append(f"seed {key}: py4dgeo's object ({len(b)} core points) missing in ours")
        elif a != b or mine[key]["threshold"] != o["threshold"]:
            lines.append(f"seed {key}: ours {len(a)} at {mine[key]['threshold']:g}, py4dgeo {len(b)} at "
                         f"{o['threshold']:g}; {len(a - b)} only ours, {len(b - a)} only py4dgeo's")
        else:
            gap = max(abs(mine[key]["members"][c] - v) for c, v in ((int(c), v) for c, v in o["members"].items()))
            lines.append(f"seed {key}: the same {len(a)} core points at {o['threshold']:g}, DTW values "
                         f"{'bit for bit' if gap == 0 else f'within {gap:.1e}'}")
    for key in set(mine) - {tuple(o["seed"]) for o in theirs}:
        lines.append(f"seed {key}: our object ({len(mine[key]['members'])} core points) missing in py4dgeo's")
    return lines


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--py4dgeo-python", default=os.environ.get("PY4DGEO_PYTHON", "/tmp/p4d/bin/python"),
                    help="an interpreter with py4dgeo 1.2.0 (a separate venv)")
    ap.add_argument("--more", type=int, default=20, help="seeds beyond the table's, summed up (0: none)")
    ap.add_argument("--child", nargs=2, type=Path, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        return py4dgeo_child(*args.child)
    from m3c2kit.series import engine
    have_py4dgeo = Path(args.py4dgeo_python).exists()
    tools = [f"ours {r}" for r in RULES] + (["py4dgeo 1.2.0"] if have_py4dgeo else [])
    names = [e.name for e in sc.EVENTS]
    rows, agreement, seconds = [], [], {t: 0.0 for t in tools}
    for seed in SEEDS:
        core, raw = sc.scene(seed)
        for series in ("raw", "smoothed", "raw, 5 % gaps"):
            d = {"raw": raw, "smoothed": engine.temporal_median(raw, WINDOW), "raw, 5 % gaps": gaps(raw, seed)}[series]
            results = {f"ours {r}": run_ours(r, core, d) for r in RULES}
            objects = {t: our_objects(out) for t, out in results.items()}
            if have_py4dgeo:
                with tempfile.TemporaryDirectory() as folder:
                    theirs = run_py4dgeo(args.py4dgeo_python, core, d, Path(folder))
                objects["py4dgeo 1.2.0"], results["py4dgeo 1.2.0"] = theirs["objects"], theirs
                ours = results["ours py4dgeo"]
                same_seeds = [list(map(int, s)) for s in zip(ours["seed_core"], ours["seed_start"],
                                                             ours["seed_end"])] == theirs["seeds"]
                agreement.append((seed, series, len(theirs["seeds"]), same_seeds,
                                  compare_members(objects["ours py4dgeo"], theirs["objects"])))
            for t in tools:
                s = sc.score(extents(objects[t], len(core)), core)
                seconds[t] += results[t]["seconds"]
                rows.append((seed, series, t, s, len(objects[t])))
    print(f"Scenes: validation/objects_scenes.py, {sc.SIDE}x{sc.SIDE} core points {sc.SPACING} m apart, "
          f"{sc.EPOCHS} epochs, noise {sc.NOISE * 1000:g} mm, seeds {', '.join(map(str, SEEDS))}; raw and smoothed "
          f"(median of {WINDOW} epochs); every tool with py4dgeo's defaults (radius 1, window 24, min period 24, "
          f"thresholds 0.1..0.9, min segments 20). Best IoU in space and time per event; found: IoU >= 0.5.\n")
    print(f"| seed | series | tool | {' | '.join(names)} | recall | precision | objects |")
    print("|---" * (len(names) + 6) + "|")
    for seed, series, t, s, n in rows:
        cells = " | ".join(f"{s['best'][k]:.2f}" for k in names)
        print(f"| {seed} | {series} | {t} | {cells} | {s['recall']:.1f} | {s['precision']:.2f} | {n} |")
    for t in tools:
        sel = [s for _, _, u, s, _ in rows if u == t]
        print(f"\n{t}: recall {np.mean([s['recall'] for s in sel]):.2f}, precision "
              f"{np.mean([s['precision'] for s in sel]):.2f} over the {len(sel)} runs, {seconds[t]:.1f} s in all", end="")
    print("\n")
    if args.more:
        more = range(SEEDS[-1] + 1, SEEDS[-1] + 1 + args.more)
        print(f"Over seeds {more.start}..{more.stop - 1} (found events of {5 * len(more)}; objects matching no event):\n")
        print("| series | tool | recall | false objects | objects |")
        print("|---|---|---|---|---|")
        for series in ("raw", "smoothed"):
            tally = {t: [0, 0, 0] for t in tools if t != "ours seed-start"}
            for seed in more:
                core, raw = sc.scene(seed)
                d = raw if series == "raw" else engine.temporal_median(raw, WINDOW)
                objects = {t: our_objects(run_ours(t.split()[1], core, d)) for t in tally if t.startswith("ours")}
                if have_py4dgeo:
                    with tempfile.TemporaryDirectory() as folder:
                        objects["py4dgeo 1.2.0"] = run_py4dgeo(args.py4dgeo_python, core, d, Path(folder))["objects"]
                for t, found in objects.items():
                    s = sc.score(extents(found, len(core)), core)
                    tally[t][0] += round(s["recall"] * len(sc.EVENTS))
                    tally[t][1] += s["false"]
                    tally[t][2] += len(found)
            for t, (hits, false, n) in tally.items():
                print(f"| {series} | {t} | {hits}/{5 * len(more)} | {false} | {n} |")
        print()
    for seed, series, n_seeds, same_seeds, lines in agreement:
        print(f"- seed {seed}, {series}: `--dtw py4dgeo` and py4dgeo's RegionGrowingAlgorithm: "
              f"{'the same' if same_seeds else 'DIFFERENT'} {n_seeds} seeds in the same order; objects:")
        for line in lines:
            print(f"  - {line}")


if __name__ == "__main__":
    main()
