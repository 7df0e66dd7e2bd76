"""base/quantiles.z_critical: the bands' normal quantile."""
from __future__ import annotations

from statistics import NormalDist

import pytest

from m3c2kit.base.quantiles import z_critical


def test_z_critical_is_the_two_sided_quantile():
    assert z_critical(0.95) == NormalDist().inv_cdf(0.975)  # the same bits as before
    for c in (0.5, 0.9, 0.99, 0.999999):
        z = z_critical(c)
        assert NormalDist().cdf(z) - NormalDist().cdf(-z) == pytest.approx(c, rel=1e-12)


def test_z_critical_at_the_last_double_below_one():
    """Issue 42: `aggregate --confidence 0.9999999999999999` ended in a StatisticsError: 0.5 + c / 2
    rounds to 1. The lower tail keeps the digits."""
    z = z_critical(0.9999999999999999)
    assert 8.0 < z < 8.5 and NormalDist().cdf(-z) == pytest.approx((1 - 0.9999999999999999) / 2, rel=1e-6)
