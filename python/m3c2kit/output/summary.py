"""The short summary `m3c2 compare` prints, with the normal-accuracy shares of section 5.1 (its
warning is m3c2kit.run.diagnostics')."""
from __future__ import annotations

import numpy as np

from ..run.diagnostics import normal_accuracy
from ..run.fdr import Fdr, sentences
from .lod_rates import expectation_text, run_expectation
from ..engine.result import Result


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
    lines += ["multiple testing: " + text for text in multiple_testing(result)]
    lines.append("status: " + ", ".join(f"{name} {count}" for name, count in result.status_counts().items()))
    acc = normal_accuracy(result)
    if acc:
        lines.append(f"normal accuracy: xi > 20 at {100 * acc['xi_over_20']:.1f}%, xi > 25 at "
                     f"{100 * acc['xi_over_25']:.1f}% of {acc['core_points']} core points with a roughness "
                     f"({acc['planar']} exactly planar, xi = inf); median predicted E_norm "
                     f"{acc['median_e_norm_percent']:.2f}%")
    return lines


def multiple_testing(result: Result) -> list[str]:
    """What the run's significance means over all its core points (the summary's and the report's
    sentences): the plain test's expected false positives, and with --fdr the expected false
    discoveries (m3c2kit.run.fdr; docs/algorithm.md, "False-discovery control")."""
    params = getattr(result, "params", {}) or {}
    fdr = Fdr.of(params)
    q = getattr(result, "significant_fdr", None) if fdr is not None else None
    tested = int(np.isfinite(np.asarray(result.p_value, dtype=float)).sum())
    return sentences(tested, int(np.asarray(result.significant).sum()), float(params.get("confidence") or 0.95),
                     fdr if q is not None else None, int(q.sum()) if q is not None else 0)
