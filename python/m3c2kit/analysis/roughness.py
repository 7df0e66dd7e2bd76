"""Roughness scaling (section 5.1, Fig. 6a, Table 1).

sigma_i(D) is the standard deviation of the distances of the neighbours within D/2 of core point i
to their least-squares plane (the engine's roughness_by_scale). Per scale D we report its mean
<sigma(D)> and standard deviation over the core points that have a value, and fit eq. (3),

    <sigma(D)> = sigma(l0) (D / l0)^beta,     l0 = 0.5 (cloud units) by default,

by least squares on log <sigma(D)> vs log(D / l0) over a chosen range of scales.
"""
from __future__ import annotations

import math

import numpy as np

from .. import engine
from ..run.checks import as_points
from ..base.errors import UsageError
from ..settings.parsers import positive
from .common import format_table, loglog_fit, pyplot, readable_log_axis, save_figure, scales

L0 = 0.5
#: sigma(D) at or below this share of D is zero to the engine's precision (docs/algorithm.md#3.3:
#: sigma(D) is accurate to 1e-12 of the neighbourhood's spread): such scales are planar and left
#: out of the eq. (3) fit, which would otherwise fit the rounding (beta ~ 3 on an exact plane).
PLANAR_SHARE = 1e-12


def roughness_by_scale(cloud, core, diameters, *, variance: str = "sample", min_points: int = 3,
                       threads: int = 0, progress=None) -> np.ndarray:
    """sigma(D) at each core point (rows) for each diameter (columns); NaN below `min_points`."""
    pts, core_pts = as_points("cloud", cloud), as_points("core", core)
    if variance not in ("sample", "population"):
        raise UsageError(f"variance must be sample or population, got {variance!r}")
    # The engine checks the integers (int() truncated 1.5 and raised ValueError on a string).
    return engine.roughness_by_scale(pts, core_pts, list(scales("diameters", diameters)), variance, min_points,
                                     threads=threads, progress=progress)


def roughness_table(sigma: np.ndarray, diameters) -> dict[str, np.ndarray]:
    """Per scale: D, mean and standard deviation (n - 1) of sigma(D) over the core points that
    have a value, and how many do."""
    sigma = np.asarray(sigma, float)
    d = np.asarray(diameters, float)
    ok = np.isfinite(sigma)
    count = ok.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        total = np.where(ok, sigma, 0.0).sum(axis=0)
        mean = np.where(count > 0, total / np.maximum(count, 1), np.nan)
        dev = np.where(ok, sigma - mean, 0.0)
        std = np.where(count > 1, np.sqrt((dev ** 2).sum(axis=0) / np.maximum(count - 1, 1)), np.nan)
    return {"D": d, "mean_sigma": mean, "std_sigma": std, "n_core": count.astype(np.int64)}


def fit_scaling(diameters, mean_sigma, fit_range: tuple[float, float] | None = None, l0: float = L0) -> dict:
    """Eq. (3): beta (the Hurst exponent) with its standard error, sigma(l0), over the scales
    D in fit_range (inclusive; all scales if None). Keys: beta, beta_se, sigma_l0, sigma_l0_factor
    (multiplicative standard error), r2, n_scales, d_min, d_max, l0."""
    l0 = positive("--l0", l0)  # a NaN, negative or infinite l0 gave NaN or 0 for sigma(l0), exit 0
    d = np.asarray(diameters, float)
    m = np.asarray(mean_sigma, float)
    sel = np.ones(len(d), bool) if fit_range is None else (d >= fit_range[0] * (1 - 1e-12)) & (d <= fit_range[1] * (1 + 1e-12))
    sel = sel & ~(m <= PLANAR_SHARE * d)  # planar to the engine's precision (NaN stays out anyway)
    fit = loglog_fit(d[sel], m[sel], l0)
    used = d[sel][np.isfinite(m[sel]) & (m[sel] > 0)]
    return {"beta": fit["slope"], "beta_se": fit["slope_se"], "sigma_l0": fit["a"], "sigma_l0_factor": fit["a_factor"],
            "r2": fit["r2"], "n_scales": fit["n"], "d_min": float(used.min()) if used.size else math.nan,
            "d_max": float(used.max()) if used.size else math.nan, "l0": float(l0), "in_fit": sel}


def report_lines(table: dict, fit: dict) -> list[str]:
    lines = format_table({"D": table["D"], "<sigma(D)>": table["mean_sigma"], "std": table["std_sigma"],
                          "n_core": table["n_core"], "fit": np.where(fit["in_fit"], "*", "")},
                         {"D": ".6g", "<sigma(D)>": ".6g", "std": ".4g", "n_core": "d"})
    lines.append(f"eq. (3) fit over D = {fit['d_min']:g} to {fit['d_max']:g} ({fit['n_scales']} scales): "
                 f"beta = {fit['beta']:.4f} +/- {fit['beta_se']:.4f} (standard error), "
                 f"sigma(l0 = {fit['l0']:g}) = {fit['sigma_l0']:.6g}, R^2 = {fit['r2']:.4f}")
    planar = np.asarray(table["mean_sigma"], float) <= PLANAR_SHARE * np.asarray(table["D"], float)
    if planar.any():
        lines.append(f"{int(planar.sum())} scale(s) with <sigma(D)> <= {PLANAR_SHARE:g} D: planar to the engine's "
                     "precision, left out of the fit" + (" (no roughness exponent: the surface is an exact plane)"
                                                          if fit["n_scales"] < 2 else ""))
    sel = fit["in_fit"] & (table["n_core"] > 0)
    if sel.any() and table["n_core"][sel].min() < 0.9 * table["n_core"].max():
        lines.append("warning: some fitted scales have sigma(D) at fewer than 90% of the core points (too few "
                     "neighbours): their mean covers a biased subset; prefer --fit-range over larger scales")
    return lines


def plot(path, table: dict, fit: dict, title: str = "") -> None:
    """Log-log plot of <sigma(D)> +/- its standard deviation against D, with the fit (Fig. 6a)."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 4.5))
    d, m, s = table["D"], table["mean_sigma"], table["std_sigma"]
    ok = np.isfinite(m) & (m > 0)
    lower = np.clip(np.nan_to_num(s[ok]), 0, m[ok] * 0.999)
    ax.errorbar(d[ok], m[ok], yerr=[lower, np.nan_to_num(s[ok])], fmt="o", ms=4, capsize=2, label="<sigma(D)> +/- std")
    if np.isfinite(fit["beta"]):
        x = np.geomspace(fit["d_min"], fit["d_max"], 50)
        ax.plot(x, fit["sigma_l0"] * (x / fit["l0"]) ** fit["beta"], "r-",
                label=f"beta = {fit['beta']:.3f} +/- {fit['beta_se']:.3f}, sigma({fit['l0']:g}) = {fit['sigma_l0']:.3g}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    if ok.any():  # labels at 1-2-5 only: the default labels every minor tick below a decade, overlapping
        readable_log_axis(ax.xaxis, float(d[ok].min()), float(d[ok].max()))
        readable_log_axis(ax.yaxis, float(m[ok].min()), float(m[ok].max()))
    ax.set_xlabel("normal scale D (diameter)")
    ax.set_ylabel("<sigma(D)>")
    ax.set_title(title or "Roughness scaling (Lague et al. 2013, Fig. 6a)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)
