"""Issue 14's summary and output defects: exactly planar core points (sigma(D) = 0, xi = inf)
count in the xi / E_norm shares, which say how many core points they cover; rows placed on a
cloud (position reference / compared) are NaN where there is no projection on that cloud; the
summary states the expected false-positive rate of the run's LOD statistic."""
from __future__ import annotations

import numpy as np
import pytest

from m3c2kit.output import lod_rates
from m3c2kit.output.report import _summary
from m3c2kit.engine.result import STATUS_NAMES, Result
from m3c2kit.output.summary import normal_accuracy, summary_lines


def make_result(normal_scale, roughness, *, n=10, params=None, i1=None, status=None) -> Result:
    m = len(roughness)
    nan = np.full(m, np.nan)
    return Result(core=np.arange(3 * m, dtype=float).reshape(m, 3), distance=np.zeros(m), lod=np.ones(m),
                  significant=np.zeros(m, bool), p_value=np.ones(m), n1=np.full(m, n, np.uint32), n2=np.full(m, n, np.uint32),
                  sigma1=nan, sigma2=nan, i1=np.zeros(m) if i1 is None else np.asarray(i1, float),
                  i2=np.ones(m), normal=np.tile([0.0, 0.0, 1.0], (m, 1)),
                  normal_scale=np.asarray(normal_scale, float), roughness=np.asarray(roughness, float),
                  status=np.zeros(m, np.uint8) if status is None else np.asarray(status, np.uint8),
                  params=params or {})


def test_planar_core_points_count_as_xi_over_25_and_are_reported():
    # The case: 230 of 385 core points on an exact plane, the others at xi = 10.
    rough = np.r_[np.zeros(230), np.full(155, 0.1)]
    r = make_result(np.full(385, 1.0), rough)
    acc = normal_accuracy(r)
    assert acc["core_points"] == 385 and acc["planar"] == 230
    assert acc["xi_over_20"] == pytest.approx(230 / 385)  # 59.7 %; it was 0 % (planar ones dropped)
    assert acc["xi_over_25"] == pytest.approx(230 / 385)
    assert acc["median_e_norm_percent"] == 0.0
    lines = summary_lines(r, "out.las")
    assert any("xi > 20 at 59.7%, xi > 25 at 59.7% of 385 core points with a roughness (230 exactly planar"
               in line for line in lines)
    rows = dict(_summary(r, 1.0))
    assert rows["xi = D / sigma(D) > 20"] == "59.7%"
    assert rows["core points with a roughness sigma(D) (exactly planar: xi = inf)"] == "385 (230)"


def test_core_points_without_roughness_are_still_left_out():
    r = make_result([1.0, np.nan, 1.0], [0.0, np.nan, np.nan])  # vertical normals: NaN D and sigma
    acc = normal_accuracy(r)
    assert acc["core_points"] == 1 and acc["planar"] == 1


@pytest.mark.parametrize("position,which", [("reference", 1), ("compared", 2)])
def test_rows_without_a_projection_are_nan_on_that_cloud(position, which):
    empty = STATUS_NAMES.index("empty_cylinder_reference")
    r = make_result([1.0, 1.0], [0.1, 0.1], i1=[0.5, np.nan], status=[0, empty])
    r.i2 = np.array([0.25, np.nan])
    table = r.columns(position=position)
    offset = 0.5 if which == 1 else 0.25
    np.testing.assert_array_equal([table["x"][0], table["y"][0], table["z"][0]], r.core[0] + [0, 0, offset])
    assert np.isnan([table["x"][1], table["y"][1], table["z"][1]]).all()  # was: the core point
    assert table["status"][1] == empty
    fallback = r.columns(position=position, fallback="core")
    np.testing.assert_array_equal([fallback["x"][1], fallback["y"][1], fallback["z"][1]], r.core[1])
    with pytest.raises(ValueError, match="fallback"):
        r.columns(position=position, fallback="zero")
    core = r.columns(position="core")
    np.testing.assert_array_equal(core["x"], r.core[:, 0])


@pytest.mark.parametrize("params,expected_lod", [({}, "auto"), ({"compat": "cloudcompare"}, "z"), ({"t_statistic": True}, "auto"),
                                                 ({"bootstrap": 100}, "bootstrap"), ({"lod": "t"}, "t")])
def test_summary_states_the_expected_false_positive_rate_at_the_median_n(params, expected_lod):
    r = make_result([1.0] * 3, [0.1] * 3, n=5, params=dict(params, confidence=0.95))
    rate = lod_rates.expected_false_positive_rate("mean", expected_lod, 0.95, 5)
    lines = summary_lines(r, "out.las")
    line = next(line for line in lines if line.startswith("expected false positives"))
    assert f"mean / {expected_lod} LOD at 95 %: about {100 * rate:.1f} %" in line
    assert "median n = 5" in line
    assert "expected false positives on unchanged surfaces" in dict(_summary(r, 1.0))


def test_no_expected_rate_for_cloudcompares_median_formula():
    r = make_result([1.0], [0.1], params={"median": True, "compat": "cloudcompare"})
    assert lod_rates.run_expectation(r) is None
    assert not any(line.startswith("expected false positives") for line in summary_lines(r, "x"))
