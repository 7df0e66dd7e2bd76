"""Validation of `m3c2 series` on the seeded synthetic series (validation/series_synthetic.py):
per-epoch distances against m3c2 compare bit for bit, 4D objects-by-change against the planted
objects (IoU in space-time) and against py4dgeo's RegionGrowingAlgorithm run on the same
smoothed series. Prints the "Time series" section of docs/validation.md (markdown).

    PYTHONPATH=python python validation/series_validation.py [--full] [--work DIR]

py4dgeo 1.2.0 runs in its own interpreter (--py4dgeo-python, a separate venv; see
validation/objects_truth.py), never beside m3c2kit."""
from __future__ import annotations

import argparse
import os
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

import series_synthetic as ss

warnings.filterwarnings("ignore")
PARAMS = dict(core_spacing=0.5, normal_scale="1", projection_scale=1.0, max_depth=1.0)
WINDOW = 5


def run_ours(s, folder: Path):
    from m3c2kit import api
    from m3c2kit.cli.main import main
    from m3c2kit.io import read_cloud
    import xarray as xr
    paths = ss.write(s, folder)
    store = folder / "st.zarr"
    t0 = time.perf_counter()
    assert main(["series", str(paths[0]), str(folder / "epochs.txt"), "-o", str(store), "--core-spacing", "0.5",
                 "--normal-scale", "1", "--projection-scale", "1", "--max-depth", "1", "--quiet"]) == 0
    t_series = time.perf_counter() - t0
    ds = xr.open_zarr(store)
    ref = read_cloud(paths[0])
    same = 0
    for k, p in enumerate(paths):
        r = api.compare(ref, read_cloud(p), **PARAMS)
        ok = all(np.array_equal(np.asarray(getattr(r, n), dtype=np.float64).view(np.uint64),
                                ds[n].values[:, k].astype(np.float64).view(np.uint64))
                 for n in ("distance", "lod", "sigma1", "sigma2"))
        same += ok
    assert main(["series", "smooth", str(store), "--window", str(WINDOW)]) == 0
    return paths, store, same, t_series


def objects_ours(store: Path, rule: str, folder: Path):
    from m3c2kit.cli.main import main
    import xarray as xr
    table = folder / f"objects_{rule}.csv"
    assert main(["series", "objects", str(store), "-o", str(table), "--quiet", "--dtw", rule]) == 0
    ds = xr.open_zarr(store)
    lab = ds["object"].values
    n = int(np.nanmax(lab)) + 1 if np.isfinite(lab).any() else 0
    return [(lab == k) for k in range(n)]


def objects_py4dgeo(store: Path, folder: Path, python: str):
    """py4dgeo's RegionGrowingAlgorithm on our smoothed series, in its own interpreter
    (validation/objects_truth.py's child)."""
    import xarray as xr
    import objects_truth
    ds = xr.open_zarr(store)
    core = np.column_stack([ds.x.values, ds.y.values, ds.z.values])
    theirs = objects_truth.run_py4dgeo(python, core, ds["smoothed_distance"].values.astype(np.float64), folder)
    masks = []
    for o in theirs["objects"]:
        m = np.zeros(ds["distance"].shape, bool)
        m[np.asarray([int(c) for c in o["members"]], dtype=int), o["seed"][1]:o["seed"][2] + 1] = True
        masks.append(m)
    return masks, theirs["seconds"]


def best(truth, found):
    if not found:
        return 0.0, -1
    scores = [ss.iou(truth, f) for f in found]
    k = int(np.argmax(scores))
    return scores[k], k


def main():
    import contextlib
    import io
    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        report()
    text = buffer.getvalue()
    text = text[text.index("Saved output"):]
    (Path(__file__).resolve().parents[1] / "docs" / "validation" / "series.md").write_text(text)
    print(text, end="")


def report():
    ap = argparse.ArgumentParser()
    ap.add_argument("--full", action="store_true", help="the full scenario (default: the reduced CI one)")
    ap.add_argument("--work", type=Path)
    ap.add_argument("--py4dgeo-python", default=os.environ.get("PY4DGEO_PYTHON", "/tmp/p4d/bin/python"),
                    help="an interpreter with py4dgeo 1.2.0 (a separate venv)")
    args = ap.parse_args()
    s = ss.Scenario() if args.full else ss.Scenario.reduced()
    folder = args.work or Path(tempfile.mkdtemp(prefix="m3c2-series-"))
    paths, store, same, t_series = run_ours(s, folder)
    import xarray as xr
    ds = xr.open_zarr(store)
    core = np.column_stack([ds.x.values, ds.y.values, ds.z.values])
    truth = ss.planted(s, core, ds.sizes["epoch"])
    paper = objects_ours(store, "baseline", folder)
    whole = objects_ours(store, "py4dgeo", folder)
    theirs, t_py4dgeo = objects_py4dgeo(store, folder, args.py4dgeo_python)
    n_points = int(s.extent ** 2 * s.density)
    print("Saved output of `PYTHONPATH=python python validation/series_validation.py`" + (" --full" if args.full else "")
          + " (py4dgeo 1.2.0 in its own venv; it writes docs/validation/series.md).\n")
    print(f"Input: `validation/series_synthetic.py`, {'full' if args.full else 'reduced (CI)'} scenario: {s.epochs} "
          f"epochs of {n_points} points on {s.extent:g} m x {s.extent:g} m, noise {s.noise} m, epoch "
          f"{s.offset_epoch} offset by {s.offset} m in z, a landslide (drop {s.landslide.drop} m at epoch "
          f"{s.landslide.onset}, then {s.landslide.rate} m per epoch), {len(s.blobs)} accumulation piles; epoch 0 "
          f"is the reference. `m3c2 series` with --core-spacing 0.5 --normal-scale 1 --projection-scale 1 "
          f"--max-depth 1 ({len(core)} core points, {t_series:.0f} s), `m3c2 series smooth --window {WINDOW}`, "
          f"`m3c2 series objects` with py4dgeo's defaults (window 24, min period 24, radius 1, thresholds "
          f"0.1..0.9, min segments 20).\n")
    print(f"- per-epoch distance, lod, sigma1, sigma2 equal to `m3c2kit.compare(reference, epoch)` bit for bit: "
          f"{same} of {len(paths)} epochs")
    print(f"- objects: ours (--dtw baseline, the default) {len(paper)}, ours (--dtw py4dgeo) "
          f"{len(whole)}, py4dgeo 1.2.0 {len(theirs)} on the same smoothed series ({t_py4dgeo:.1f} s)\n")
    print("| planted object | core points | IoU ours | IoU ours --dtw py4dgeo | IoU py4dgeo | IoU ours vs py4dgeo |")
    print("|---|---|---|---|---|---|")
    for name, m in truth:
        a, ka = best(m, paper)
        b, kb = best(m, whole)
        c, kc = best(m, theirs)
        agree = ss.iou(whole[kb], theirs[kc]) if kb >= 0 and kc >= 0 else 0.0
        print(f"| {name} | {int(m.any(1).sum())} | {a:.3f} | {b:.3f} | {c:.3f} | {agree:.3f} |")
    unmatched = [k for k, f in enumerate(theirs) if max((ss.iou(f, m) for _, m in truth), default=0) < 0.5]
    print(f"\npy4dgeo objects matching no planted object (IoU < 0.5): {len(unmatched)}; ours: "
          f"{sum(max((ss.iou(f, m) for _, m in truth), default=0) < 0.5 for f in paper)}; ours --dtw py4dgeo: "
          f"{sum(max((ss.iou(f, m) for _, m in truth), default=0) < 0.5 for f in whole)}.\n")
    print(EXPLANATION)


EXPLANATION = """Both tools get the same seeds in the same order under `--dtw py4dgeo` (checked: identical seed
lists), and from them the same objects (IoU 1.000 above; validation/objects_truth.py checks the
members and their DTW values bit for bit, docs/series.md "Analysis"). Notes:

- **Neighbour order.** py4dgeo visits a core point's neighbours in its kd-tree's leaf order
  (nanoflann, unsorted); we visit them in ascending index. A visit can move the 95th-percentile
  residual that decides which members grow the object further, so the objects could differ at
  their edges; on this series and on objects_truth.py's scenes they do not.
- **Before `--dtw`**, `--whole-series` (said to be py4dgeo's) compared the whole series and took
  the neighbours at exactly the radius, which py4dgeo leaves out: it grew the landslide to 0.981
  and an extra object from a pile's removal (a seed running to the end of the series).
- **The default, `--dtw baseline`**, measures each series from its median before the change and
  starts each object at the epoch before it: the landslide 0.979 and the first pile 0.860, where
  py4dgeo's rule has 0.931 and 0.816.
- **Where py4dgeo is wrong.** Nothing here; its temporal_averaging (not used: both tools read our
  `smooth` output) omits the last epoch from every window, and its seed search writes the
  interpolated NaN epochs into the analysis' own distance array (docs/series.md)."""


if __name__ == "__main__":
    main()
