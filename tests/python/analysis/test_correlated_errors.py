"""--error-model is calibrated (issue 34): the excess estimator on a case with a known answer, and
a reduced version of validation/correlated_errors.py (one correlation length, independent trials,
real compare runs) whose flagged share must lie in the binomial 99 % interval around 5 %."""
import sys
import types
from pathlib import Path

import numpy as np
import pytest

from m3c2kit.analysis.error_model import Component, ErrorModel
from m3c2kit.analysis.random_fields import sample_field
from m3c2kit.analysis.variogram import eq1_variance, fit_error_model

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "validation"))


def _grid(n: int) -> np.ndarray:
    g = np.arange(n, dtype=np.float64)
    x, y = np.meshgrid(g, g, indexing="ij")
    return np.c_[x.ravel(), y.ravel(), np.zeros(x.size)]


@pytest.mark.parametrize("range_", [3.0, 0.3])
def test_excess_estimator_known_answer(range_):
    # Core points every 1 with eq. (1)'s variance u_i^2 known (its sigma / n columns, varying from
    # point to point) and a correlated part of variance 4e-5: of range 3 (its sill a partial sill)
    # or 0.3, shorter than the spacing, so that it lands in the nugget. Either way the excess must
    # be 4e-5; the sum of partial sills (the estimator before) sees ~0 of the short one.
    rng = np.random.default_rng(21)
    pts = _grid(100)
    n1, n2 = rng.integers(5, 40, len(pts)).astype(float), rng.integers(5, 40, len(pts)).astype(float)
    s1, s2 = rng.uniform(0.005, 0.02, len(pts)), rng.uniform(0.005, 0.02, len(pts))
    u2 = eq1_variance(types.SimpleNamespace(fields={"sigma1": s1, "sigma2": s2, "n1": n1, "n2": n2}, path="t"))
    assert np.allclose(u2, s1 ** 2 / n1 + s2 ** 2 / n2, rtol=1e-15)
    truth = 4e-5
    field = ErrorModel(0.0, (Component("spherical", truth, range_),))
    correlated = sample_field(pts[:, :2], field, 3) if range_ > 1 else rng.normal(0, np.sqrt(truth), len(pts))
    distance = rng.normal(0.0, np.sqrt(u2)) + correlated
    distance[::97] = np.nan  # core points without a distance are left out of both sums
    fitted = fit_error_model(pts, distance, u2, seed=1, threads=2)
    ok = np.isfinite(distance)
    assert fitted.used == ok.sum() and fitted.model.mean_u2 == pytest.approx(np.mean(u2[ok]), rel=1e-12)
    # the truth, within the sampling error of a difference of two variances (about 5 % here)
    assert fitted.model.excess_variance() == pytest.approx(truth, rel=0.15)
    # and the variogram's total sill against the plain sample variance (no correlation beyond the
    # area here, so the two agree)
    assert fitted.model.total_variance() == pytest.approx(np.var(distance[ok]), rel=0.05)
    if range_ < 1:
        assert fitted.model.correlated_variance() < 0.5 * truth  # what eq. (1) + sills alone would miss
    assert not fitted.warnings


def test_range_comparable_to_the_area_is_warned():
    pts = _grid(40)
    field = ErrorModel(0.0, (Component("spherical", 1e-4, 15.0),))
    fitted = fit_error_model(pts, sample_field(pts[:, :2], field, 5), np.full(len(pts), 1e-6), seed=1, threads=2)
    assert fitted.warnings and "over 0.25 of the stable core points' extent" in fitted.warnings[0]


@pytest.mark.slow
def test_error_model_flags_five_percent_of_independent_stable_core_points():
    import correlated_errors as ce
    # R = d, the hardest length: core points every d leave no lag below the correlation, which all
    # lands in the nugget. 8 surveys x 100 trials farther apart than R + d (the validation's design)
    case = ce.Case(1.0, 30.0, 8, 77)
    surveys = [ce.run_survey(case, i, threads=2, far_pairs=2_000_000) for i in range(case.surveys)]
    s = ce.summarise(case, surveys)
    lo, hi = s.interval
    assert s.trials >= 750
    assert lo <= s.share_model <= hi, (s.share_model, s.interval)
    assert s.share_eq1 > 4 * 0.05  # eq. (1) alone flags several times more
    assert abs(s.excess_bias) < 0.15
