"""The short summary `m3c2 compare` prints, with the normal-accuracy check of section 5.1."""
from __future__ import annotations

import numpy as np

from .lod_rates import expectation_text, run_expectation
from .result import Result


def normal_accuracy(result: Result) -> dict:
    """Shares of core points with xi = D / sigma(D) > 20 and > 25, and the median predicted
    E_norm = 1.3e5 xi^-3.5 (%), eq. (5) of section 5.1, over the core points with a roughness
    (`core_points` of them, `planar` with sigma(D) = 0: xi = inf counts as > 25, E_norm 0);
    {} where none has one."""
    with np.errstate(divide="ignore", invalid="ignore"):
        xi = result.xi
    xi = xi[np.isfinite(result.roughness) & np.isfinite(result.normal_scale)]
    if xi.size == 0:
        return {}
    with np.errstate(divide="ignore"):
        e_norm = 1.3e5 * xi ** -3.5  # 0 where xi = inf
    return {"xi_over_20": float(np.mean(xi > 20)), "xi_over_25": float(np.mean(xi > 25)),
            "median_e_norm_percent": float(np.median(e_norm)), "core_points": int(xi.size),
            "planar": int(np.sum(np.isinf(xi)))}


def summary_lines(result: Result, output) -> list[str]:
    n = len(result)
    ok = np.isfinite(result.distance)
    lines = [f"wrote {output}: {n} core points, {int(ok.sum())} with a distance, "
             f"{int(result.significant.sum())} significant changes"]
    if ok.any():
        d = result.distance[ok]
        lines.append(f"distance: median {np.median(d):.4f}, mean {np.mean(d):.4f}, min {d.min():.4f}, max {d.max():.4f}")
    lod = result.lod[np.isfinite(result.lod)]
    if lod.size:
        lines.append(f"LOD: median {np.median(lod):.4f}, min {lod.min():.4f}, max {lod.max():.4f}")
        expected = run_expectation(result)
        if expected:
            lines.append("expected false positives: " + expectation_text(expected))
    lines.append("status: " + ", ".join(f"{name} {count}" for name, count in result.status_counts().items()))
    acc = normal_accuracy(result)
    if acc:
        lines.append(f"normal accuracy: xi > 20 at {100 * acc['xi_over_20']:.1f}%, xi > 25 at "
                     f"{100 * acc['xi_over_25']:.1f}% of {acc['core_points']} core points with a roughness "
                     f"({acc['planar']} exactly planar, xi = inf); median predicted E_norm "
                     f"{acc['median_e_norm_percent']:.2f}%")
        if acc["xi_over_20"] < 0.5:
            lines.append("warning: most core points have xi = D / sigma(D) < 20: the normals are affected by "
                         "roughness (section 5.1); consider a larger --normal-scale")
    return lines
