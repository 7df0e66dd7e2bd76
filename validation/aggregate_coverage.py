"""Aggregates over regions: do ``m3c2 aggregate``'s 95 % intervals cover the true mean change and
volume 95 % of the time when the errors are spatially correlated? (issue 34; docs/validation.md,
"Aggregates over a region").

1. Direct simulation (400 surveys per case). The core points of a grid run (64 x 64 cells of
   1 m) carry a known change (0.3 m on the west half, -0.1 m elsewhere) plus an error: a
   correlated Gaussian field of a known model (m3c2kit.analysis.random_fields.sample_field, a new
   seed per survey) plus iid noise of the u_i^2 the result's sigma/n columns state. Three regions:
   the west half (32 x 64 m), a patch (16 x 20 m) in the east, and their union (the total row).
   m3c2kit.analysis.aggregate computes the intervals with the true model and without any model;
   the coverage of the true mean and volume over the surveys is compared with the binomial 99 %
   interval of 0.95. Correlation ranges of 4, 12 and 32 m (spherical) and 12 m (exponential):
   shorter than, about, and longer than the regions. The significant area's bootstrap standard
   error (50 simulated surveys each, on the first 40 surveys) is compared with the actual spread
   of the significant area across the 400 surveys.
2. End to end (3 surveys): two epochs of points (0.25 m jittered grid over 24 x 24 m), each with
   its own correlated field (spherical, sill SIGMA_FIELD^2, range 8 m) and iid noise, the change
   of part 1 in the west; ``m3c2 compare --grid 1`` then ``m3c2 aggregate`` with the model of
   the difference of the two fields (partial sill 2 SIGMA_FIELD^2, the disc averaging over d =
   1.1 m neglected: it lowers the variance by under 2 % at this range) through the command line.

Run ``python validation/aggregate_coverage.py`` for docs/validation/aggregate_coverage.{md,png}.
tests/python/analysis/test_aggregate.py runs a reduced part 1.
"""
from __future__ import annotations

import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from m3c2kit.analysis.aggregate import Survey, aggregate
from m3c2kit.analysis.error_model import Component, ErrorModel, save
from m3c2kit.analysis.random_fields import sample_field
from m3c2kit.io.polygons import Polygon, region_index

REPO = Path(__file__).resolve().parents[1]
CELL = 1.0
SIDE = 64
SURVEYS = 400
SIGMA_U = 0.02          # m, the iid part of each core point's distance
SILL = 1.0e-3           # m^2, the correlated part's variance (sigma_c = 3.2 cm)
BOOT_SURVEYS, BOOT_K = 40, 50
CASES = (("spherical", 4.0), ("spherical", 12.0), ("spherical", 32.0), ("exponential", 12.0))


def square(name, x0, y0, x1, y1) -> Polygon:
    return Polygon(name, [np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], float)])


REGIONS = [square("west", 0, 0, 32, 64), square("patch", 40, 20, 56, 40)]


def lattice(side: int, cell: float) -> np.ndarray:
    c, r = np.meshgrid(np.arange(side), np.arange(side))
    return np.column_stack([(c.ravel() + 0.5) * cell, (r.ravel() + 0.5) * cell])


def truth_of(xy: np.ndarray, split: float = 32.0) -> np.ndarray:
    """The true change: 0.3 m west of x = split, -0.1 m east of it."""
    return np.where(xy[:, 0] < split, 0.3, -0.1)


def binomial_99(p: float, n: int) -> tuple[float, float]:
    """The central 99 % interval of the share of n Bernoulli(p) trials (exact, from the pmf)."""
    k = np.arange(n + 1)
    logpmf = (np.array([math.lgamma(n + 1) - math.lgamma(i + 1) - math.lgamma(n - i + 1) for i in k])
              + k * math.log(p) + (n - k) * math.log1p(-p))
    cdf = np.cumsum(np.exp(logpmf))
    return float(np.searchsorted(cdf, 0.005) / n), float(np.searchsorted(cdf, 0.995) / n)


def direct_case(kind: str, range_: float, surveys: int = SURVEYS, seed: int = 34) -> dict:
    xy = lattice(SIDE, CELL)
    model = ErrorModel(0.0, (Component(kind, SILL, range_),))
    u2 = np.full(len(xy), SIGMA_U ** 2)
    truth = truth_of(xy)
    inside = np.stack([region_index(xy, [p]) == 0 for p in REGIONS])
    masks = [inside[0], inside[1], inside.any(axis=0)]
    true_mean = [float(truth[m].mean()) for m in masks]
    lod = np.full(len(xy), 1.96 * math.sqrt(SIGMA_U ** 2))  # eq. (1)'s LOD of these u_i
    cover = {"model": np.zeros((3, 2), int), "none": np.zeros((3, 2), int)}
    se = {"model": np.zeros(3), "none": np.zeros(3)}
    sig_counts, boot_se = [], []
    for s in range(surveys):
        rng = np.random.default_rng([seed, s])
        d = truth + sample_field(xy, model, seed * 100_003 + s) + rng.standard_normal(len(xy)) * SIGMA_U
        survey = Survey(xy, d, lod, u2)
        for name, m in (("model", model), ("none", None)):
            k = BOOT_K if (name == "model" and s < BOOT_SURVEYS) else 0
            t = aggregate(survey, REGIONS, model=m, cell=CELL, simulations=k, seed=s)
            for r, row in enumerate(t.rows):
                true_volume = true_mean[r] * row.with_distance * CELL * CELL
                cover[name][r, 0] += row.mean_low <= true_mean[r] <= row.mean_high
                cover[name][r, 1] += row.volume_low <= true_volume <= row.volume_high
                se[name][r] += row.mean_se / surveys
            if name == "model":
                sig_counts.append([row.significant for row in t.rows])
                if k:
                    boot_se.append([row.significant_se for row in t.rows])
    return {"kind": kind, "range": range_, "surveys": surveys, "cover": cover, "se": se,
            "sig_sd": np.std(np.array(sig_counts, float), axis=0, ddof=1),
            "boot_se": np.mean(np.array(boot_se, float), axis=0)}


def end_to_end(runs: int = 3, seed: int = 77) -> list[dict]:
    from m3c2kit.cli.main import main
    sigma_field, sigma_iid, range_, side, spacing = 0.01, 0.01, 8.0, 24.0, 0.25
    point_model = ErrorModel(0.0, (Component("spherical", sigma_field ** 2, range_),))
    distance_model = ErrorModel(0.0, (Component("spherical", 2 * sigma_field ** 2, range_),))
    regions_wkt = "POLYGON ((0 0, 12 0, 12 24, 0 24, 0 0))\nPOLYGON ((14 6, 22 6, 22 18, 14 18, 14 6))\n"
    out = []
    for run in range(runs):
        rng = np.random.default_rng([seed, run])
        g = np.stack(np.meshgrid(np.arange(0, side, spacing), np.arange(0, side, spacing)), -1).reshape(-1, 2)
        epochs = []
        for e in range(2):
            xy = g + rng.uniform(-spacing / 3, spacing / 3, g.shape)
            z = sample_field(xy, point_model, seed * 1000 + 10 * run + e) + rng.normal(0, sigma_iid, len(xy))
            if e == 1:
                z = z + truth_of(xy, split=12.0)
            epochs.append(np.column_stack([xy, z]))
        with tempfile.TemporaryDirectory() as tmp:
            tmp = Path(tmp)
            for name, pts in zip(("ref.npy", "cmp.npy"), epochs):
                np.save(tmp / name, pts)
            save(tmp / "model.json", distance_model)
            (tmp / "regions.wkt").write_text(regions_wkt)
            assert main(["compare", str(tmp / "ref.npy"), str(tmp / "cmp.npy"), "-o", str(tmp / "r.csv"),
                         "--grid", "1", "--max-depth", "1.5", "-q"]) == 0
            assert main(["aggregate", str(tmp / "r.csv"), "--regions", str(tmp / "regions.wkt"), "-o",
                         str(tmp / "t.csv"), "--cell-size", "1", "--error-model", str(tmp / "model.json"),
                         "--simulations", "20", "-q"]) == 0
            import csv
            rows = list(csv.DictReader(open(tmp / "t.csv")))
            result = np.genfromtxt(tmp / "r.csv", delimiter=",", names=True)
        # the truth over the core points that have a distance (the compare grid's own cells)
        cells = np.column_stack([result["x"], result["y"]])[np.isfinite(result["distance"])]
        inside = np.stack([region_index(cells, [p]) == 0 for p in
                           (square("0", 0, 0, 12, 24), square("1", 14, 6, 22, 18))])
        truth = [float(truth_of(cells, split=12.0)[m].mean()) for m in (inside[0], inside[1], inside.any(0))]
        for r, row in enumerate(rows):
            mean, se = float(row["mean"]), float(row["mean_se"])
            out.append({"run": run, "region": row["region"], "truth": truth[r], "mean": mean, "se": se,
                        "se_unc": float(row["se_uncorrelated"]), "z": (mean - truth[r]) / se,
                        "covered": float(row["mean_low"]) <= truth[r] <= float(row["mean_high"])})
    return out


def main() -> int:
    out = REPO / "docs" / "validation"
    out.mkdir(parents=True, exist_ok=True)
    start = time.time()
    results = [direct_case(k, r) for k, r in CASES]
    e2e = end_to_end()
    lo, hi = binomial_99(0.95, SURVEYS)
    lines = ["# Aggregates over a region: coverage of the 95 % intervals (validation/aggregate_coverage.py)", "",
             f"{SURVEYS} simulated surveys per case; binomial 99 % interval of a 95 % coverage over {SURVEYS}: "
             f"[{lo:.3f}, {hi:.3f}]. Core points on a {SIDE} x {SIDE} grid of {CELL:g} m; iid error "
             f"{SIGMA_U} m; correlated sill {SILL:g} m^2. Regions: west 32 x 64 m, patch 16 x 20 m, total their "
             "union.", "",
             "| model | range (m) | region | coverage of the mean, with the model | of the volume | "
             "without a model (uncorrelated) | mean se with / without (m) | in the 99 % interval |",
             "|---|---|---|---|---|---|---|---|"]
    ok_all = True
    for res in results:
        for r, name in enumerate(("west", "patch", "total")):
            c = res["cover"]["model"][r] / res["surveys"]
            cn = res["cover"]["none"][r] / res["surveys"]
            ok = lo <= c[0] <= hi and lo <= c[1] <= hi
            ok_all &= ok
            lines.append(f"| {res['kind']} | {res['range']:g} | {name} | {c[0]:.3f} | {c[1]:.3f} | {cn[0]:.3f} | "
                         f"{res['se']['model'][r]:.4f} / {res['se']['none'][r]:.4f} | {'yes' if ok else 'NO'} |")
    lines += ["", "Significant area (cells with |distance| > LOD): its spread across the surveys against the "
              f"bootstrap's standard error (mean over the first {BOOT_SURVEYS} surveys, {BOOT_K} simulations each):",
              "", "| model | range (m) | region | sd across surveys (cells) | mean bootstrap se (cells) |",
              "|---|---|---|---|---|"]
    for res in results:
        for r, name in enumerate(("west", "patch", "total")):
            lines.append(f"| {res['kind']} | {res['range']:g} | {name} | {res['sig_sd'][r]:.1f} | "
                         f"{res['boot_se'][r]:.1f} |")
    lines += ["", "End to end (`m3c2 compare --grid 1` on two simulated epochs, then `m3c2 aggregate`):", "",
              "| run | region | true mean (m) | estimated (m) | se (m) | uncorrelated se (m) | z | covered |",
              "|---|---|---|---|---|---|---|---|"]
    for e in e2e:
        lines.append(f"| {e['run']} | {e['region']} | {e['truth']:.4f} | {e['mean']:.4f} | {e['se']:.4f} | "
                     f"{e['se_unc']:.4f} | {e['z']:+.2f} | {'yes' if e['covered'] else 'no'} |")
    lines += ["", f"Every direct case in the binomial interval: {'yes' if ok_all else 'NO'}. "
              f"Runtime {time.time() - start:.0f} s."]
    (out / "aggregate_coverage.md").write_text("\n".join(lines) + "\n")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(8, 4))
    labels, width = [], 0.38
    for i, res in enumerate(results):
        for r, name in enumerate(("west", "patch", "total")):
            x = i * 3 + r
            ax.bar(x - width / 2, res["cover"]["model"][r, 0] / res["surveys"], width, color="tab:blue",
                   label="with the error model" if x == 0 else None)
            ax.bar(x + width / 2, res["cover"]["none"][r, 0] / res["surveys"], width, color="tab:orange",
                   label="uncorrelated (no model)" if x == 0 else None)
            labels.append(f"{res['kind'][:3]} {res['range']:g} m\n{name}")
    ax.axhspan(lo, hi, color="0.85", label="binomial 99 % of 0.95")
    ax.set_xticks(range(len(labels)), labels, fontsize=7)
    ax.set_ylabel("coverage of the true mean")
    ax.set_ylim(0, 1.02)
    ax.legend(fontsize=8, loc="lower left")
    ax.set_title(f"95 % intervals of the regional mean, {SURVEYS} surveys per case")
    fig.tight_layout()
    fig.savefig(out / "aggregate_coverage.png", dpi=120)
    print("\n".join(lines))
    return 0 if ok_all else 1


if __name__ == "__main__":
    sys.exit(main())
