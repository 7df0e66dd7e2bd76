"""random_fields.sample_field: deterministic, and its empirical variogram is its model's."""
import numpy as np
import pytest

from m3c2kit.analysis.error_model import Component, ErrorModel
from m3c2kit.analysis.random_fields import sample_field


def test_deterministic():
    xy = np.random.default_rng(0).uniform(0, 30, (500, 2))
    m = ErrorModel(0.1, (Component("spherical", 1.0, 5.0),))
    a, b = sample_field(xy, m, 3), sample_field(xy, m, 3)
    assert np.array_equal(a, b) and not np.array_equal(a, sample_field(xy, m, 4))
    assert not np.array_equal(a, sample_field(xy, m, 3, include_nugget=True))


@pytest.mark.parametrize("kind", ["spherical", "exponential"])
def test_empirical_variogram_is_the_model(kind):
    # An ensemble of fields at fixed pairs of points: 0.5 E[(f_i - f_j)^2] per lag is gamma(h).
    rng = np.random.default_rng(1)
    lags = np.array([1.0, 2.0, 4.0, 8.0, 16.0])  # from range / 8 (the module's docstring)
    start = rng.uniform(0, 40, (len(lags) * 40, 2))
    angle = rng.uniform(0, 2 * np.pi, len(start))
    h = np.repeat(lags, 40)
    end = start + h[:, None] * np.c_[np.cos(angle), np.sin(angle)]
    m = ErrorModel(0.0, (Component(kind, 1.0, 8.0),))
    xy = np.r_[start, end]
    d2 = []
    for seed in range(60):
        f = sample_field(xy, m, seed)
        d2.append(0.5 * (f[: len(start)] - f[len(start):]) ** 2)
    gamma = np.mean(d2, axis=0).reshape(len(lags), 40).mean(axis=1)
    var = np.mean([sample_field(xy[:200], m, s) ** 2 for s in range(60)])
    assert var == pytest.approx(1.0, abs=0.06)
    assert np.allclose(gamma, m.variogram(lags), rtol=0.12, atol=0.02), (gamma, m.variogram(lags))
