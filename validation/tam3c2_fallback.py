"""TAM3C2's two extensions (docs/series.md, "TAM3C2", "Fallback and window breaks"; issue 41) on
the seeded scenes of tests/python/series/test_tam3c2_store.py, each over several seeds:

1. completeness per epoch (a dense reference, sparse epochs of about 1.5 points per cylinder,
   rising 1 cm an hour): the share of core points with a distance from per-epoch M3C2, TAM3C2 with
   the authors' rule (--fallback none) and with ours (--fallback m3c2), how many of the latter are
   the epoch's own M3C2, and the median |error| to the truth; on the test's scene (10 epochs from
   0.25 h to 24 h, the defaults --required-points 10 --window-ratio 0.2: no window ever reaches 10
   points) and on one where later windows do (16 epochs, --required-points 5 --window-ratio 0.5);
2. a 5 cm step from hour 7 (epochs every hour, --window-ratio 1): the median |error| to the truth
   per epoch with --window-breaks none and changepoints.

    .venv/bin/python validation/tam3c2_fallback.py [--seeds 3]

Prints markdown tables."""
from __future__ import annotations

import argparse
import contextlib
import io
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "python" / "series"))
from test_tam3c2_store import (NEAR_HOURS, REF_TIME, RISE, STEP, STEP_AT, STEP_HOURS,  # noqa: E402
                               make_store, step_height)

import xarray as xr  # noqa: E402
from m3c2kit.cli.main import main as cli  # noqa: E402
from m3c2kit.series import store as st  # noqa: E402


def tam3c2(store: Path, *options: str) -> xr.Dataset:
    with contextlib.redirect_stdout(io.StringIO()):
        assert cli(["series", "tam3c2", str(store), "--reference-time", REF_TIME, *options]) == 0
    return xr.open_zarr(store).load()


#: The second completeness scene: epochs near the reference and later ones close enough to borrow.
LATER_HOURS = [0.25, 0.5, 1, 2, 3, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24]


def completeness(folder: Path, seeds, hours, *options: str) -> None:
    n = len(hours)
    plain, none, ours, own = (np.zeros(n) for _ in range(4))
    errors = {"M3C2": [], "none": [], "m3c2": []}
    truth = RISE * np.array(hours, dtype=float)
    cells = 0
    for seed in seeds:
        store = make_store(Path(tempfile.mkdtemp(dir=folder)), hours, lambda h: RISE * h, seed)
        ds = tam3c2(store, *options, "--fallback", "none")
        plain += np.isfinite(ds["distance"].values).sum(0)
        none += np.isfinite(ds["tam3c2_distance"].values).sum(0)
        errors["M3C2"].append(ds["distance"].values - truth)
        errors["none"].append(ds["tam3c2_distance"].values - truth)
        ds = tam3c2(store, *options, "--fallback", "m3c2")
        ours += np.isfinite(ds["tam3c2_distance"].values).sum(0)
        own += (ds["tam3c2_window"].values == st.TAM3C2_FROM_EPOCH).sum(0)
        errors["m3c2"].append(ds["tam3c2_distance"].values - truth)
        cells += ds.sizes["core"]
    e = {k: np.abs(np.vstack(v)) for k, v in errors.items()}
    cm = lambda a: f"{100 * float(np.nanmedian(a)):.2f} cm"  # noqa: E731
    print(f"Completeness per epoch, {' '.join(options)} ({len(seeds)} seeds, {cells} core points per epoch; "
          f"the median |error| to the truth in brackets):\n")
    print("| hour | M3C2 | TAM3C2, --fallback none | TAM3C2, --fallback m3c2 | of which the epoch's own |")
    print("|---|---|---|---|---|")
    share = lambda v: f"{100 * v / cells:.1f} %"  # noqa: E731
    for k, h in enumerate(hours):
        print(f"| {h:g} | {share(plain[k])} ({cm(e['M3C2'][:, k])}) | {share(none[k])} ({cm(e['none'][:, k])}) | "
              f"{share(ours[k])} ({cm(e['m3c2'][:, k])}) | {share(own[k])} |")
    print(f"| all | {share(plain.sum() / n)} ({cm(e['M3C2'])}) | {share(none.sum() / n)} ({cm(e['none'])}) | "
          f"{share(ours.sum() / n)} ({cm(e['m3c2'])}) | {share(own.sum() / n)} |\n")


def step_error(folder: Path, seeds) -> None:
    truth = np.array([step_height(h) for h in STEP_HOURS])
    errors = {b: [] for b in ("none", "changepoints")}
    plain = []
    for seed in seeds:
        store = make_store(Path(tempfile.mkdtemp(dir=folder)), STEP_HOURS, step_height, seed)
        for breaks in errors:
            ds = tam3c2(store, "--window-ratio", "1", "--window-breaks", breaks)
            errors[breaks].append(ds["tam3c2_distance"].values - truth)
        plain.append(ds["distance"].values - truth)
    print(f"Median |error| per epoch, a {100 * STEP:g} cm step from hour {STEP_AT} ({len(seeds)} seeds; "
          f"--window-ratio 1, --fallback m3c2):\n")
    print("| hour | truth | M3C2 | TAM3C2, --window-breaks none | TAM3C2, --window-breaks changepoints |")
    print("|---|---|---|---|---|")
    e = {b: np.vstack(v) for b, v in errors.items()}
    p = np.vstack(plain)
    for k, h in enumerate(STEP_HOURS):
        cm = lambda a: f"{100 * float(np.nanmedian(np.abs(a[:, k]))):.2f} cm"  # noqa: E731
        print(f"| {h} | {100 * truth[k]:g} cm | {cm(p)} | {cm(e['none'])} | {cm(e['changepoints'])} |")
    print()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    args = ap.parse_args()
    seeds = [41 + k for k in range(args.seeds)]
    with tempfile.TemporaryDirectory() as tmp:
        completeness(Path(tmp), seeds, NEAR_HOURS, "--required-points", "10", "--window-ratio", "0.2")
        completeness(Path(tmp), seeds, LATER_HOURS, "--required-points", "5", "--window-ratio", "0.5")
        step_error(Path(tmp), seeds)
    return 0


if __name__ == "__main__":
    sys.exit(main())
