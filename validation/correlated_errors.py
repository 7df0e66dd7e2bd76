"""Spatially correlated errors: is ``--error-model`` calibrated? (issue 34; docs/validation.md,
"Spatially correlated errors").

A simulated survey: a flat plane sampled twice on jittered grids (SPACING, a new draw per epoch),
each epoch with iid noise SIGMA_IID along z PLUS its own independent correlated field (a
spherical variogram of sill SIGMA_FIELD^2 and range R, m3c2kit.analysis.random_fields);
no change. M3C2 (m3c2kit.compare) with vertical normals at d = D, 95 % LOD, eq. (1) with z.

Design (independent trials). Each survey has three strips along x:
- the FIT region, F x F, with core points every d (as a user runs it): its plain compare result
  gives the error model exactly as ``m3c2 variogram`` computes it (analysis.variogram.
  fit_error_model: the variogram, the fit, mean(s1^2/n1 + s2^2/n2), the excess);
- a GAP of R + 2d with no core point;
- the TRIAL region: core points on a lattice of step R + 2d, each counted once, with and without
  the model (real compare runs: ``error_model=`` the saved MODEL.json). Two discs of diameter d
  whose centres are more than R + d apart share no correlated pair, so the trials' errors are
  independent of each other and of the fitted data (the gap); epoch points in the trial region
  are drawn only within d of a trial (nothing else reads them: vertical normals, the cylinder).
Given the fitted model, a survey's trials are independent Bernoulli draws; across surveys they
share nothing. The share flagged is compared with the binomial 99 % interval of all trials at
p = 5 %, and, because trials of one survey share the fitted sill, with a survey-level check too:
the between-survey variance of the per-survey share against the binomial one (the design effect)
and a 99 % interval from the survey means (t, surveys - 1 dof).

Truth for the fit: the distance's correlated part is the difference of two independent fields
averaged over each cylinder's points, whose variance beyond eq. (1) is 2 disc_mean_variance(d)
of the point model (m3c2kit.analysis.error_model; docs/algorithm.md derives why the excess
estimates exactly that).

Run ``python validation/correlated_errors.py`` for the table and the plot of docs/validation.md
(docs/validation/correlated_errors.{md,png}); tests/python/analysis/test_correlated_errors.py
runs a reduced case through :func:`run_survey`.
"""
from __future__ import annotations

import math
import sys
import tempfile
import time
import types
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

import m3c2kit
from m3c2kit.analysis.error_model import Component, ErrorModel, save
from m3c2kit.analysis.random_fields import sample_field
from m3c2kit.analysis.variogram import eq1_variance, fit_error_model

REPO = Path(__file__).resolve().parents[1]
SIGMA_IID = 0.005    # m, per point
SIGMA_FIELD = 0.008  # m, each epoch's correlated field (the 8 mm)
D = 1.0              # projection scale d
SPACING = 0.25       # m, each epoch's point spacing: about 12 points per cylinder
CONFIDENCE = 0.95


@dataclass(frozen=True)
class Case:
    range_: float   # the point field's range R
    fit_side: float  # F: the fit region is F x F
    surveys: int
    seed: int

    @property
    def step(self) -> float:
        """The trials' lattice step (and the gap): R + 2d > R + d, the disc means' reach."""
        return self.range_ + 2.0 * D


@dataclass(frozen=True)
class Survey:
    fit_excess: float   # the model's excess variance (sigma_c^2 of the LOD)
    fit_sill: float     # its sum of partial sills (the shared part, covariance(0))
    fit_range: float    # the range of the component with the largest sill
    fit_u2: float       # the model's mean_u2
    trials: int         # trial core points with a LOD in both runs
    flagged_eq1: int
    flagged_model: int
    warned: bool        # m3c2 variogram's finite-area warning


def point_model(case: Case) -> ErrorModel:
    return ErrorModel(0.0, (Component("spherical", SIGMA_FIELD ** 2, case.range_),))


def true_excess(case: Case) -> float:
    """The variance of a core point's distance not counted by eq. (1): 2 disc_mean_variance(d)."""
    return 2.0 * point_model(case).disc_mean_variance(D)


def _layout(case: Case) -> tuple[np.ndarray, np.ndarray, tuple[float, float]]:
    """(fit core points, trial core points, (x_max, y_max) of the area)."""
    F, T = case.fit_side, case.step
    g = np.arange(D / 2, F, D)
    cx, cy = np.meshgrid(g, g, indexing="ij")
    fit = np.c_[cx.ravel(), cy.ravel(), np.zeros(cx.size)]
    tx = F + T + T / 2 + T * np.arange(int(F // T))
    ty = T / 2 + T * np.arange(int(F // T))
    ax, ay = np.meshgrid(tx, ty, indexing="ij")
    trials = np.c_[ax.ravel(), ay.ravel(), np.zeros(ax.size)]
    return fit, trials, (float(tx[-1] + T / 2), F)


def _epoch(case: Case, trials: np.ndarray, box: tuple[float, float], seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    gx, gy = np.arange(0.0, box[0], SPACING), np.arange(0.0, box[1], SPACING)
    x, y = np.meshgrid(gx, gy, indexing="ij")
    xy = np.c_[x.ravel(), y.ravel()] + rng.uniform(-0.5, 0.5, (x.size, 2)) * SPACING
    # the fit region whole; beyond it only the trials' discs (+ a margin): nothing else is read
    far = xy[:, 0] > case.fit_side
    if far.any():
        T = case.step
        i = np.rint((xy[:, 0] - case.fit_side - 1.5 * T) / T)
        j = np.rint((xy[:, 1] - 0.5 * T) / T)
        cxy = np.c_[case.fit_side + 1.5 * T + i * T, 0.5 * T + j * T]
        near = (np.hypot(*(xy - cxy).T) < D) & (i >= 0)
        xy = xy[~far | near]
    z = rng.normal(0.0, SIGMA_IID, len(xy)) + sample_field(xy, point_model(case), seed + 1000)
    return np.c_[xy, z]


def run_survey(case: Case, index: int, threads: int = 0, far_pairs: int = 10_000_000) -> Survey:
    """One simulated survey (seeded by the case's seed and `index`): the model fitted on its fit
    region, the trials flagged with eq. (1) alone and with the model."""
    fit, trials, box = _layout(case)
    base = 1_000_003 * case.seed + 1009 * index
    one, two = _epoch(case, trials, box, base + 1), _epoch(case, trials, box, base + 2)
    common = dict(projection_scale=D, max_depth=0.2, normal_source="vertical", confidence=CONFIDENCE, lod="z",
                  threads=threads)
    plain_fit = m3c2kit.compare(one, two, fit, **common)
    u2 = eq1_variance(types.SimpleNamespace(fields={k: getattr(plain_fit, k) for k in ("sigma1", "sigma2", "n1", "n2")},
                                            path="the fit region's result"))
    fitted = fit_error_model(fit, plain_fit.distance, u2, seed=index, far_pairs=far_pairs, threads=threads)
    model = replace(fitted.model, projection_scale=D)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "model.json"
        save(path, model)
        modelled = m3c2kit.compare(one, two, trials, error_model=str(path), **common)
    plain = m3c2kit.compare(one, two, trials, **common)
    ok = np.isfinite(plain.lod) & np.isfinite(modelled.lod)
    main = max(model.components, key=lambda c: c.sill)
    return Survey(model.excess_variance(), model.correlated_variance(), main.range, model.mean_u2, int(ok.sum()),
                  int(np.sum(plain.significant[ok] == 1)), int(np.sum(modelled.significant[ok] == 1)),
                  bool(fitted.warnings))


def binomial_interval(n: int, p: float = 1 - CONFIDENCE, level: float = 0.99) -> tuple[float, float]:
    """The central `level` interval of the share of n Bernoulli(p) draws (scipy's binomial)."""
    from scipy.stats import binom
    a = (1 - level) / 2
    return binom.ppf(a, n, p) / n, binom.isf(a, n, p) / n


@dataclass(frozen=True)
class Summary:
    case: Case
    trials: int
    share_eq1: float
    share_model: float
    interval: tuple[float, float]      # binomial 99 % of all trials at p = 5 %
    survey_interval: tuple[float, float]  # 99 % t interval of the per-survey shares' mean
    design_effect: float               # between-survey variance of the shares / binomial's
    excess_bias: float                 # mean fitted excess / truth - 1
    excess_spread: float               # their relative standard deviation over surveys
    explained: float                   # the share the fitted excess's error alone predicts
    range_median: float                # median fitted main range
    warned: int


def summarise(case: Case, surveys: list[Survey]) -> Summary:
    from scipy.stats import t as student
    n = np.array([s.trials for s in surveys], dtype=np.float64)
    k = np.array([s.flagged_model for s in surveys], dtype=np.float64)
    share = k.sum() / n.sum()
    per = k / n
    # the design effect: the per-survey shares' variance over what independent trials would give
    binom_var = np.mean(share * (1 - share) / n)
    deff = float(np.var(per, ddof=1) / binom_var) if binom_var > 0 and len(per) > 1 else float("nan")
    half = student.ppf(0.995, len(per) - 1) * np.std(per, ddof=1) / math.sqrt(len(per))
    excess = np.array([s.fit_excess for s in surveys]) / true_excess(case)
    # what each survey's sigma_c^2 error alone predicts (the true variance taken as the survey's
    # mean_u2 + the true excess): the convexity of the share in the estimated variance
    from scipy.stats import norm
    u2 = np.array([s.fit_u2 for s in surveys])
    ratio = (u2 + np.array([s.fit_excess for s in surveys])) / (u2 + true_excess(case))
    explained = float(np.average(2 * norm.sf(norm.isf((1 - CONFIDENCE) / 2) * np.sqrt(ratio)), weights=n))
    return Summary(case, int(n.sum()), sum(s.flagged_eq1 for s in surveys) / n.sum(), float(share),
                   binomial_interval(int(n.sum())), (float(np.mean(per) - half), float(np.mean(per) + half)), deff,
                   float(np.mean(excess) - 1), float(np.std(excess, ddof=1)), explained,
                   float(np.median([s.fit_range for s in surveys])), sum(s.warned for s in surveys))


CASES = (Case(1.0, 30.0, 40, 1), Case(4.0, 64.0, 40, 2), Case(16.0, 160.0, 40, 3))


def table(rows: list[Summary]) -> list[str]:
    out = ["| R / d | fit region (m) | surveys x trials | true sigma_c^2 (mm^2) | fitted sigma_c^2: mean error "
           "(sd over surveys) | fitted range, median (m) | flagged, eq. (1) | flagged, --error-model | binomial "
           "99 % interval (all trials) | design effect | 99 % interval (survey means) | share the sill's error "
           "predicts |", "|" + "---|" * 12]
    for r in rows:
        c = r.case
        lo, hi = r.interval
        slo, shi = r.survey_interval
        inside = "" if lo <= r.share_model <= hi else " **outside**"
        out.append(f"| {c.range_ / D:g} | {c.fit_side:g} x {c.fit_side:g} | {c.surveys} x {r.trials // c.surveys} | "
                   f"{true_excess(c) * 1e6:.1f} | {r.excess_bias:+.0%} ({r.excess_spread:.0%}) | "
                   f"{r.range_median:.2f} | {r.share_eq1:.1%} | {r.share_model:.2%}{inside} | [{lo:.2%}, {hi:.2%}] | "
                   f"{r.design_effect:.2f} | [{slo:.2%}, {shi:.2%}] | {r.explained:.2%} |")
    return out


def main() -> int:
    out = REPO / "docs" / "validation"
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for case in CASES:
        t = time.perf_counter()
        surveys = [run_survey(case, i) for i in range(case.surveys)]
        r = summarise(case, surveys)
        rows.append(r)
        print(f"R = {case.range_:g} d: {r.trials} trials, flagged eq. (1) {r.share_eq1:.1%}, with the model "
              f"{r.share_model:.2%} {r.interval}, design effect {r.design_effect:.2f}, excess {r.excess_bias:+.1%} "
              f"({time.perf_counter() - t:.0f} s)", flush=True)
    lines = table(rows)
    (out / "correlated_errors.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    from m3c2kit.analysis.common import pyplot
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 3.8))
    x = np.arange(len(rows))
    ax.bar(x - 0.2, [r.share_eq1 * 100 for r in rows], 0.4, label="eq. (1)", color="#c0392b")
    ax.bar(x + 0.2, [r.share_model * 100 for r in rows], 0.4, label="--error-model", color="#2980b9")
    for i, r in enumerate(rows):
        ax.plot([i + 0.2, i + 0.2], [r.interval[0] * 100, r.interval[1] * 100], color="black", lw=2)
        ax.text(i - 0.2, r.share_eq1 * 100, f"{r.share_eq1:.0%}", ha="center", va="bottom", fontsize=8)
        ax.text(i + 0.2, r.share_model * 100, f"{r.share_model:.1%}", ha="center", va="bottom", fontsize=8)
    ax.axhline(5, color="gray", ls=":")
    ax.set_xticks(x, [f"R = {r.case.range_ / D:g} d\n{r.trials} trials" for r in rows])
    ax.set_ylabel("stable core points flagged (%)")
    ax.set_title("No change, correlated errors: 95 % LOD (black: binomial 99 % interval)", fontsize=10)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "correlated_errors.png", dpi=120)
    return 0


if __name__ == "__main__":
    sys.exit(main())
