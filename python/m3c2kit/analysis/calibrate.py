"""LOD95 calibration on one cloud (sections 5.2.1 and 5.2.2, Figs. 8 and 9).

A surface compared with a differently subsampled copy of itself has not changed, so a correct
95 % level of detection should call about 95 % of core points "not significant". For each
projection scale d we compare cloud 1 and cloud 2 (the cloud at two minimum spacings: the paper's
raw vs 10 cm, and 4.5 vs 5 cm) with three LODs: eq. (1) with z, eq. (1) with Welch's t and the DF
of eq. (2) when n1 or n2 < 30, and the bootstrap of Appendix B. Like the paper ("We impose a fixed
normal direction"), normals are vertical unless a normal scale D is given.

Every LOD statistic of the engine is measured as well (issue 14): the share of core points each of
mean / median x z / t / auto / bootstrap flags (`fp_<statistic>_<lod>`, nominal 1 - confidence),
and, per d, the one whose rate is closest to the nominal (`recommended`; ties to the cheaper:
z, auto, t, bootstrap); `recommend()` sums this up over the scales.

The mean LOD95 (z) is then fitted as LOD95 ~ d^alpha and compared with eq. (7), alpha = beta - 0.95,
where beta is the roughness exponent of eq. (3) measured on the same cloud and core points over
the same scales (and with beta - gamma / 2, gamma the measured exponent of n ~ d^gamma: the paper's
0.95 is 1.9 / 2).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..run import in_memory
from ..run.checks import as_points
from . import lod_engine
from ..base.errors import UsageError
from ..engine.result import STATUS_OK
from .common import (format_table, loglog_fit, median_spacing, pyplot, readable_log_axis, reference_line,
    sample_indices, save_figure)
from .roughness import L0, fit_scaling, roughness_by_scale, roughness_table


def resolve_spacing(spec, spacing: float) -> float:
    """'raw' or 0 -> 0 (no subsampling); 'Nx' -> N times the median point spacing; a number."""
    text = str(spec).strip().lower()
    if text in ("raw", "0", "0.0"):
        return 0.0
    try:
        value = float(text[:-1]) * spacing if text.endswith("x") else float(text)
    except ValueError:
        raise UsageError(f"--spacings: {spec!r} is not 'raw', a number or a multiple of the point spacing 'Nx'") from None
    if text.endswith("x") and not (math.isfinite(spacing) and spacing > 0):
        raise UsageError(f"--spacings: {spec!r} is a multiple of the median point spacing, which the cloud does "
                         f"not have (fewer than two distinct points); give a length")
    if not (math.isfinite(value) and value > 0):
        raise UsageError(f"--spacings: {spec!r} gives a spacing that is not finite and > 0 ({value:g})")
    return value


def _version(points: np.ndarray, spacing: float) -> np.ndarray:
    return points if spacing == 0 else points[in_memory.subsample(points, spacing)]


@dataclass(frozen=True)
class ComparisonSettings:
    """The M3C2 settings of every comparison of cloud 1 with cloud 2, d aside."""

    normal_scale: object = None  # D (one value, a list or MIN:MAX:STEP); None: vertical normals, as the paper
    max_depth: float | None = None  # the cylinder's half-length; None: the largest d
    min_points: int = 4  # points needed in each cylinder for a LOD (5.2.1)
    confidence: float = 0.95
    orient: object = "+z"


@dataclass(frozen=True)
class CorePoints:
    """Where the comparisons are measured: `given` points, else the cloud subsampled to `spacing`,
    else to the coarser of cloud 1's and cloud 2's spacings (at least 4 times the median point
    spacing); at most `max_count` of them (None: all), drawn with the run's seed."""

    given: object = None
    spacing: float | None = None
    max_count: int | None = 2000


@dataclass(frozen=True)
class FitSettings:
    """The log-log fits (LOD95 ~ d^alpha, eq. (3)): the d in `range` (MIN, MAX; None: all), l0 of eq. (3)."""

    range: tuple[float, float] | None = None
    l0: float = L0


def calibrate(cloud, projection_scales, *, spacings=("raw", "3x"),
              comparison: ComparisonSettings = ComparisonSettings(), cores: CorePoints = CorePoints(),
              bootstrap: int = 100, seed: int = 0, fit: FitSettings = FitSettings(), threads: int = 0) -> dict:
    """Runs the calibration; returns {'table': columns per d, 'fit': ..., 'info': ...}. `seed`
    draws the core points and the bootstrap's resamples (`bootstrap`: their number, 0: none)."""
    normal_scale, confidence = comparison.normal_scale, comparison.confidence
    fit_range, l0 = fit.range, fit.l0
    pts = as_points("cloud", cloud)
    d_list = np.asarray(projection_scales, float)
    if len(spacings) != 2:
        raise UsageError(f"--spacings needs two values (cloud 1, cloud 2), got {len(spacings)}")
    spacing = median_spacing(pts)
    s1, s2 = (resolve_spacing(s, spacing) for s in spacings)
    cloud1, cloud2 = _version(pts, s1), _version(pts, s2)
    if cores.given is not None:
        core_pts = as_points("core", cores.given)
    elif cores.spacing:
        core_pts = pts[in_memory.subsample(pts, cores.spacing)]
    else:
        core_pts = _version(pts, max(s1, s2, 4 * spacing))
    core_pts = np.ascontiguousarray(core_pts[sample_indices(len(core_pts), cores.max_count, seed)])
    depth = float(comparison.max_depth) if comparison.max_depth is not None else float(d_list.max())
    common = dict(projection_scale=None, max_depth=depth, min_points=comparison.min_points, confidence=confidence,
                  orient=comparison.orient, threads=threads)
    if normal_scale is None:
        common["normal_source"] = "vertical"
    else:
        common["normal_scale"] = normal_scale
    runs = {"z": {"lod": "z"}, "t": {"lod": "auto"}}  # "t": the paper's rule, t below 30 points
    if bootstrap:
        runs["bootstrap"] = {"bootstrap": int(bootstrap), "seed": int(seed)}

    rows = {k: [] for k in ("d", "n_lod_z", "pct_not_significant_z", "pct_not_significant_t",
                            "pct_not_significant_bootstrap", "mean_lod95", "median_lod95", "mean_n1", "mean_n2")}
    for d in d_list:
        common["projection_scale"] = float(d)
        out = {}
        for name, extra in runs.items():
            r = in_memory.compare(cloud1, cloud2, core_pts, **common, **extra)
            valid = r.status == STATUS_OK
            out[name] = (r, valid, 100.0 * float(np.mean(~r.significant[valid])) if valid.any() else math.nan)
        r, valid, pct = out["z"]
        searched = np.isfinite(r.distance)
        rows["d"].append(float(d))
        rows["n_lod_z"].append(int(valid.sum()))
        rows["pct_not_significant_z"].append(pct)
        rows["pct_not_significant_t"].append(out["t"][2])
        rows["pct_not_significant_bootstrap"].append(out["bootstrap"][2] if "bootstrap" in out else math.nan)
        rows["mean_lod95"].append(float(np.mean(r.lod[valid])) if valid.any() else math.nan)
        rows["median_lod95"].append(float(np.median(r.lod[valid])) if valid.any() else math.nan)
        rows["mean_n1"].append(float(np.mean(r.n1[searched])) if searched.any() else math.nan)
        rows["mean_n2"].append(float(np.mean(r.n2[searched])) if searched.any() else math.nan)
    table = {k: np.asarray(v) for k, v in rows.items()}
    table.update(_every_statistic(cloud1, cloud2, core_pts, d_list, common, bootstrap, seed, confidence))

    # Roughness of the same cloud at the same core points, D = each d (eq. 3), for eq. (7).
    sigma = roughness_by_scale(pts, core_pts, d_list, min_points=10, threads=threads)
    rough = roughness_table(sigma, d_list)
    table["mean_sigma_D"] = rough["mean_sigma"]
    sel = np.ones(len(d_list), bool) if fit_range is None else (d_list >= fit_range[0]) & (d_list <= fit_range[1])
    lod_fit = loglog_fit(d_list[sel], table["mean_lod95"][sel], l0)
    n_fit = loglog_fit(d_list[sel], np.sqrt(table["mean_n1"][sel] * table["mean_n2"][sel]), l0)
    beta = fit_scaling(d_list, rough["mean_sigma"], fit_range, l0)
    fit = {"alpha": lod_fit["slope"], "alpha_se": lod_fit["slope_se"], "lod_l0": lod_fit["a"], "n_scales": lod_fit["n"],
           "beta": beta["beta"], "beta_se": beta["beta_se"], "sigma_l0": beta["sigma_l0"],
           "alpha_predicted": beta["beta"] - 0.95, "gamma": n_fit["slope"],
           "alpha_predicted_gamma": beta["beta"] - n_fit["slope"] / 2, "l0": l0}
    info = {"spacing": spacing, "spacing1": s1, "spacing2": s2, "points1": len(cloud1), "points2": len(cloud2),
            "core_points": len(core_pts), "max_depth": depth,
            "normals": "vertical (imposed)" if normal_scale is None else f"reference, D = {normal_scale}",
            "bootstrap": int(bootstrap), "seed": int(seed), "confidence": float(confidence)}
    return {"table": table, "fit": fit, "info": info, "recommendation": recommend(table, confidence)}


#: The LOD statistics compared, cheapest first (the order that breaks ties).
COMBINATIONS = tuple((s, lod) for s in lod_engine.STATISTICS for lod in ("z", "auto", "t", "bootstrap"))


def _every_statistic(cloud1, cloud2, core_pts, d_list, common, bootstrap, seed, confidence) -> dict:
    """fp_<statistic>_<lod> per d: the share of core points with a LOD flagged significant."""
    cols = {f"fp_{s}_{lod}": [] for s, lod in COMBINATIONS}
    cols["recommended"] = []
    threads = common.get("threads", 0)
    for d in d_list:
        kwargs = {k: v for k, v in common.items() if k != "threads"}
        kwargs["projection_scale"] = float(d)
        for statistic, lod in COMBINATIONS:
            if lod == "bootstrap" and not bootstrap:
                cols[f"fp_{statistic}_{lod}"].append(math.nan)
                continue
            extra = {"bootstrap": int(bootstrap), "seed": int(seed)} if lod == "bootstrap" else {}
            r = in_memory.compare(cloud1, cloud2, core_pts, median=statistic == "median", lod=lod, threads=threads,
                            **kwargs, **extra)
            ok = r.status == STATUS_OK
            cols[f"fp_{statistic}_{lod}"].append(float(np.mean(r.significant[ok])) if ok.any() else math.nan)
        rates = {k: cols[f"fp_{k[0]}_{k[1]}"][-1] for k in COMBINATIONS}
        cols["recommended"].append(_closest(rates, 1 - confidence))
    return {k: np.asarray(v) for k, v in cols.items()}


def _closest(rates: dict, nominal: float) -> str:
    finite = [(abs(r - nominal), i, k) for i, (k, r) in enumerate(rates.items()) if math.isfinite(r)]
    if not finite:
        return ""
    return "/".join(min(finite)[2])


def recommend(table: dict, confidence: float) -> dict:
    """Per statistic (mean, median): the LOD whose no-change false-positive rate, averaged over
    the scales, is closest to the nominal 1 - confidence; {'mean': (lod, rate), 'median': ...}."""
    out = {}
    for statistic in lod_engine.STATISTICS:
        best = None
        for rank, (s, lod) in enumerate(COMBINATIONS):
            if s != statistic:
                continue
            v = np.asarray(table[f"fp_{s}_{lod}"], float)
            if not np.isfinite(v).any():
                continue
            rate = float(np.nanmean(v))
            key = (abs(rate - (1 - confidence)), rank)
            if best is None or key < best[0]:
                best = (key, lod, rate)
        if best:
            out[statistic] = (best[1], best[2])
    return out


def report_lines(res: dict) -> list[str]:
    t, f, i = res["table"], res["fit"], res["info"]

    def label(s):
        return "raw" if s == 0 else f"{s:g}"
    lines = [f"cloud 1: {label(i['spacing1'])} ({i['points1']} points), cloud 2: {label(i['spacing2'])} "
             f"({i['points2']} points); median point spacing {i['spacing']:.4g}; {i['core_points']} core points; "
             f"normals {i['normals']}; max depth {i['max_depth']:g}"]
    lines += format_table({"d": t["d"], "n_lod": t["n_lod_z"], "%ns z": t["pct_not_significant_z"],
                           "%ns t": t["pct_not_significant_t"], "%ns boot": t["pct_not_significant_bootstrap"],
                           "mean LOD95": t["mean_lod95"], "<n1>": t["mean_n1"], "<n2>": t["mean_n2"],
                           "<sigma(D=d)>": t["mean_sigma_D"]},
                          {"d": ".4g", "n_lod": "d", "%ns z": ".1f", "%ns t": ".1f", "%ns boot": ".1f",
                           "mean LOD95": ".4g", "<n1>": ".1f", "<n2>": ".1f", "<sigma(D=d)>": ".4g"})
    lines.append("%ns = percentage of core points with a LOD correctly found NOT significant (95 % expected)")
    fp_cols = {f"{s[:3]} {lod}": t[f"fp_{s}_{lod}"] * 100 for s, lod in COMBINATIONS}
    lines.append("no-change false positives (%) of every LOD statistic (nominal "
                 f"{100 * (1 - i.get('confidence', 0.95)):g} %):")
    lines += format_table({"d": t["d"], **fp_cols, "closest": t["recommended"]},
                          {"d": ".4g", **{k: ".1f" for k in fp_cols}, "closest": "s"})
    for statistic, (lod, rate) in res.get("recommendation", {}).items():
        lines.append(f"recommended with the {statistic}: --lod {lod} ({100 * rate:.1f} % false positives over "
                     "these scales)")
    lines.append(f"LOD95 ~ d^alpha: alpha = {f['alpha']:.3f} +/- {f['alpha_se']:.3f} over {f['n_scales']} scales; "
                 f"roughness beta = {f['beta']:.3f} +/- {f['beta_se']:.3f}: eq. (7) predicts beta - 0.95 = "
                 f"{f['alpha_predicted']:.3f}; with the measured n ~ d^{f['gamma']:.2f}, beta - gamma/2 = "
                 f"{f['alpha_predicted_gamma']:.3f}")
    return lines


def plot(path, res: dict, title: str = "") -> None:
    """Fig. 8 (percentage not significant vs d) and Fig. 9 (mean LOD95 vs d, log-log)."""
    plt = pyplot()
    t, f = res["table"], res["fit"]
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2))
    for key, lab in (("pct_not_significant_z", "eq. (1), z"), ("pct_not_significant_t", "eq. (1)-(2), Welch t"),
                     ("pct_not_significant_bootstrap", "bootstrap")):
        if np.isfinite(t[key]).any():
            a.plot(t["d"], t[key], "o-", ms=4, label=lab)
    a.axhline(95, color="k", ls="--", lw=0.8)
    a.set_xscale("log")
    a.set_xlabel("projection scale d (diameter)")
    a.set_ylabel("% correctly not significant")
    a.legend(fontsize=8)
    a.grid(True, which="both", alpha=0.3)
    ok = np.isfinite(t["mean_lod95"]) & (t["mean_lod95"] > 0)
    b.loglog(t["d"][ok], t["mean_lod95"][ok], "o", label="mean LOD95 (eq. 1)")
    if np.isfinite(f["alpha"]):
        x = np.geomspace(t["d"][ok].min(), t["d"][ok].max(), 50)
        b.loglog(x, f["lod_l0"] * (x / f["l0"]) ** f["alpha"], "r-", label=f"alpha = {f['alpha']:.3f}")
        if np.isfinite(f["alpha_predicted"]):
            # The predicted slope is a slope, not a fit: drawn through the fitted line's value at
            # the data's geometric centre (anchored at l0 it ran decades off the data when l0 lies
            # outside the scales measured).
            xc = float(np.sqrt(x[0] * x[-1]))
            yc = f["lod_l0"] * (xc / f["l0"]) ** f["alpha"]
            b.loglog(x, reference_line(x, yc, xc, f["alpha_predicted"]), "g--",
                     label=f"beta - 0.95 = {f['alpha_predicted']:.3f} (slope)")
    b.set_xlabel("projection scale d (diameter)")
    b.set_ylabel("mean LOD95")
    if ok.any():
        readable_log_axis(b.xaxis, float(t["d"][ok].min()), float(t["d"][ok].max()))
        readable_log_axis(a.xaxis, float(t["d"][ok].min()), float(t["d"][ok].max()))
    b.legend(fontsize=8)
    b.grid(True, which="both", alpha=0.3)
    fig.suptitle(title or "LOD95 calibration (Lague et al. 2013, Figs. 8-9)")
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)
