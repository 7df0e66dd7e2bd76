"""Our TAM3C2 (include/m3c2/tam3c2.hpp) against the authors' code on shared seeded synthetic
series (docs/series.md, "TAM3C2"): `TAM3C2` of src/py4dgeo/tam3c2.py in the fork xyuhuang/py4dgeo
(Huang et al., ISPRS Annals 2026), run through its `calculate_distances(reference, target)` for
every target, for each weighting with several normal radii and window ratios.

Ours is configured to their model (critical value 1.96, +z orientation, the same cylinder,
registration error, min points), so the distances and LODs must agree to rounding (1e-9). Their
code is run, never copied: give the path of their file and a Python with py4dgeo and scipy, kept
apart from m3c2kit's environment. Where the file comes from: it is in no branch of the fork's
public repository snapshot (main, 0f60116, nor tam3c2-test and the others), only in the code
index, at commit 45285b0a0f6e7af55481bb42bceb54fa42534a04: the table in docs/series.md was made
with a whole transcription of it, kept outside this repository (two independent transcriptions
agree on every statement both hold).

    python -m venv /tmp/tam_ref_venv && /tmp/tam_ref_venv/bin/pip install py4dgeo scipy
    .venv/bin/python validation/tam3c2_reference.py --python /tmp/tam_ref_venv/bin/python \\
        --tam3c2 TRANSCRIPT/tam3c2.py

It prints a markdown table (docs/series.md) of the largest differences and exits 1 when one
exceeds 1e-9."""
from __future__ import annotations

import argparse
import datetime as dt
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from statistics import NormalDist

SEED = 20260301
CASES = {  # name: (weights, space_time_ratio)
    "none": ("none", 1.0),
    "linear": ("linear", 1.0),
    "gaussian": ("gaussian", 1.5),
}
COMMON = dict(normal_radii=[0.5, 1.0], window_ratios=[0.3, 1.0], min_points=12, cylinder_radius=0.35,
              max_distance=1.0, sigma_ratio=1.0, registration_error=0.02)


def synthetic(seed: int = SEED, n_epochs: int = 12):
    """Shared series: a tilted rough plane rising 2 cm a day, epochs of 15 to 300 points (many
    too sparse for one cylinder), irregular times in whole seconds; 40 core points."""
    rng = np.random.default_rng(seed)
    start = dt.datetime(2024, 3, 1, 6, 0, 0)
    seconds = np.cumsum(rng.integers(8, 60, n_epochs)) * 3600
    clouds = []
    for s in seconds:
        n = int(rng.choice([15, 40, 120, 300]))
        x, y = rng.uniform(-2, 2, n), rng.uniform(-2, 2, n)
        z = 0.2 * x - 0.1 * y + 0.02 * s / 86400 + 0.05 * np.sin(3 * x) + rng.normal(0, 0.01, n)
        clouds.append(np.column_stack([x, y, z]))
    core = np.column_stack([rng.uniform(-1.2, 1.2, 40), rng.uniform(-1.2, 1.2, 40), np.zeros(40)])
    dates = [start + dt.timedelta(seconds=int(s)) for s in seconds]
    return dates, clouds, core


# ----------------------------------------------------------------------------------------------
# The reference side: run in the other Python (--python), imports their module from its file.

def _reference_side(tam3c2_path: Path, folder: Path) -> None:
    import importlib.util
    spec = importlib.util.spec_from_file_location("tam3c2_reference", tam3c2_path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    import py4dgeo
    dates, clouds, core = synthetic()
    ref = 2
    for name, (weights, r_st) in CASES.items():
        epochs = [py4dgeo.Epoch(c.copy(), timestamp=d) for c, d in zip(clouds, dates)]
        tam = module.TAM3C2(epochs_timeseries=epochs, max_window_ratio=COMMON["window_ratios"],
                            normal_radii=COMMON["normal_radii"], required_points=COMMON["min_points"],
                            weighting=module.Weighting(weights),
                            sigma_ratio=COMMON["sigma_ratio"], space_time_ratio=r_st, corepoints=core,
                            cyl_radius=COMMON["cylinder_radius"],
                            max_distance=COMMON["max_distance"], registration_error=COMMON["registration_error"])
        d, lod, n1, n2 = [], [], [], []
        for t in range(len(epochs)):
            dist, unc = tam.calculate_distances(epochs[ref], epochs[t])
            d.append(dist), lod.append(unc["lodetection"]), n1.append(unc["num_samples1"]), n2.append(unc["num_samples2"])
        np.savez(folder / f"{name}.npz", distance=np.column_stack(d), lod=np.column_stack(lod),
                 n1=np.column_stack(n1), n2=np.column_stack(n2), normal=tam.directions())


# ----------------------------------------------------------------------------------------------

def _ours(name: str) -> dict:
    from m3c2kit import engine as facade
    dates, clouds, core = synthetic()
    seconds = np.array([(d - dates[0]).total_seconds() for d in dates])
    weights, r_st = CASES[name]
    pool = facade.tam3c2_pool(clouds, seconds / 86400.0)
    # their rule: neither of our extensions (docs/series.md, "Fallback and window breaks")
    s = dict(COMMON, weights=weights, space_time_ratio=r_st, orientation=[0.0, 0.0, 1.0],
             confidence=2 * NormalDist().cdf(1.96) - 1, fallback="none", breaks="none")  # their fixed z = 1.96
    return facade.tam3c2(pool, core, 2, range(len(clouds)), s)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--python", help="the Python with py4dgeo and scipy (reference side)")
    ap.add_argument("--tam3c2", type=Path, help="their src/py4dgeo/tam3c2.py")
    ap.add_argument("--reference-side", type=Path, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.reference_side:
        _reference_side(args.tam3c2, args.reference_side)
        return 0
    if not (args.python and args.tam3c2):
        ap.error("give --python and --tam3c2")
    with tempfile.TemporaryDirectory() as tmp:
        # in the temporary folder: py4dgeo writes its py4dgeo.log into the working directory
        subprocess.run([args.python, str(Path(__file__).resolve()), "--tam3c2", str(args.tam3c2.resolve()),
                        "--reference-side", tmp], cwd=tmp,
                       check=True)
        rows, worst = [], 0.0
        for name in CASES:
            theirs, ours = np.load(Path(tmp) / f"{name}.npz"), _ours(name)
            same_nan = np.array_equal(np.isnan(theirs["distance"]), np.isnan(ours["distance"]))
            dd = float(np.nanmax(np.abs(theirs["distance"] - ours["distance"])))
            dl = float(np.nanmax(np.abs(theirs["lod"] - ours["lod"])))
            # their num_samples are cast to int64 in _m3c2_and_lod's record: floor of Kish's n
            dn = float(np.nanmax(np.abs(theirs["n2"] - np.floor(ours["n2"]))))
            computed = int(np.isfinite(ours["distance"]).sum())
            rows.append(f"| {name} | {computed} / {ours['distance'].size} | {same_nan} | {dd:.2e} | {dl:.2e} | {dn:.0f} |")
            worst = max(worst, dd, dl) if same_nan else float("inf")
    print("| weights | distances computed | same NaN | max abs diff distance | max abs diff LOD | n2 (floored) |")
    print("|---|---|---|---|---|---|")
    print("\n".join(rows))
    print(json.dumps({"worst": worst}))
    return 0 if worst <= 1e-9 else 1


if __name__ == "__main__":
    sys.exit(main())
