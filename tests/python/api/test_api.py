"""The Python API against the engine and against analytic answers."""
import numpy as np
import pytest

import m3c2kit
from m3c2kit import _core
from m3c2kit.settings import build_params

from synthetic import noisy_plane_pair

PARAMS = dict(normal_scale=0.5, projection_scale=0.3, max_depth=0.5)


def test_compare_recovers_a_known_offset():
    ref, cmp = noisy_plane_pair(offset=0.1)
    core = ref[(ref[:, 0] > 1) & (ref[:, 0] < 5) & (ref[:, 1] > 1) & (ref[:, 1] < 5)][::7]
    r = m3c2kit.compare(ref, cmp, core, **PARAMS)
    assert (r.status == 0).all()
    # 2 mm noise averaged over ~28 points per cylinder: the mean is within 1 mm of 0.1.
    assert abs(np.mean(r.distance) - 0.1) < 1e-3
    assert r.significant.all()
    np.testing.assert_allclose(r.normal[:, 2], 1.0, atol=1e-3)


def test_inputs_are_viewed_not_copied():
    ref, cmp = noisy_plane_pair(n=40)
    r = m3c2kit.compare(ref, cmp, ref, **PARAMS)
    assert np.shares_memory(r.core, ref)


def test_api_matches_the_engine_field_by_field():
    ref, cmp = noisy_plane_pair(n=60)
    core = ref[::11].copy()
    r = m3c2kit.compare(ref, cmp, core, median=True, **PARAMS)
    p = build_params(median=True, **PARAMS)
    raw = _core.compute(ref, cmp, core, p)
    for name in ("distance", "lod", "n1", "n2", "sigma1", "sigma2", "i1", "i2", "normal", "normal_scale",
                 "roughness", "status"):
        np.testing.assert_array_equal(getattr(r, name), raw[name], err_msg=name)
    np.testing.assert_array_equal(r.significant, raw["significant"].astype(bool))


def test_core_spacing_subsamples_the_reference():
    ref, cmp = noisy_plane_pair(n=60)
    r = m3c2kit.compare(ref, cmp, core_spacing=0.3, **PARAMS)
    d = np.linalg.norm(r.core[:, None, :] - r.core[None, :, :], axis=-1)
    np.fill_diagonal(d, np.inf)
    assert d.min() >= 0.3 and 20 < len(r) < len(ref)


@pytest.mark.parametrize("spec, expected", [
    ("0.5:2.5:0.5", [0.5, 1.0, 1.5, 2.0, 2.5]),
    ("0.1:0.3:0.1", [0.1, 0.2, 0.30000000000000004]),
    ("1,2,4", [1.0, 2.0, 4.0]),
    (2, [2.0]),
    ([0.5, 1], [0.5, 1.0]),
])
def test_normal_scale_syntax(spec, expected):
    assert list(build_params(normal_scale=spec, projection_scale=1, max_depth=1).normal_diameters) == pytest.approx(expected)


@pytest.mark.parametrize("bad, option", [
    (dict(projection_scale=0), "--projection-scale"),
    (dict(projection_scale=float("nan")), "--projection-scale"),
    (dict(max_depth=-1), "--max-depth"),
    (dict(normal_scale="1:0.5:0.1"), "--normal-scale"),
    (dict(normal_scale="a"), "--normal-scale"),
    (dict(confidence=1.5), "--confidence"),
    (dict(min_points=0), "--min-points"),
    (dict(bootstrap=1), "--bootstrap"),
    (dict(registration_error=-0.1), "--registration-error"),
    (dict(orient="sideways"), "--orient"),
    (dict(normal_source="sky"), "--normal-source"),
])
def test_bad_parameters_name_the_option(bad, option):
    ref, cmp = noisy_plane_pair(n=20)
    with pytest.raises(m3c2kit.UsageError, match=option):
        m3c2kit.compare(ref, cmp, **{**PARAMS, **bad})


def test_missing_normal_scale_is_a_usage_error_unless_normals_are_imposed():
    ref, cmp = noisy_plane_pair(n=20)
    with pytest.raises(m3c2kit.UsageError, match="--normal-scale"):
        m3c2kit.compare(ref, cmp, projection_scale=0.3, max_depth=0.5)
    r = m3c2kit.compare(ref, cmp, projection_scale=0.3, max_depth=0.5, normal_source="vertical")
    np.testing.assert_array_equal(r.normal[:, 2], 1.0)


def test_compat_cloudcompare_switches_to_population_variance():
    ref, cmp = noisy_plane_pair(n=60)
    core = ref[::13].copy()
    ours = m3c2kit.compare(ref, cmp, core, depth_search="single", min_points=4, **PARAMS)
    cc = m3c2kit.compare(ref, cmp, core, compat="cloudcompare", depth_search="single", min_points=4, **PARAMS)
    n = ours.n1.astype(float)
    np.testing.assert_allclose(cc.sigma1, ours.sigma1 * np.sqrt((n - 1) / n), rtol=1e-12)


def test_core_normals_are_used_as_given():
    ref, cmp = noisy_plane_pair(n=40)
    core = ref[::9].copy()
    tilted = np.tile([0.0, 0.6, 0.8], (len(core), 1))
    r = m3c2kit.compare(ref, cmp, core, normal_source="core", core_normals=tilted, projection_scale=0.3, max_depth=0.5)
    np.testing.assert_allclose(r.normal, tilted)
    with pytest.raises(m3c2kit.UsageError, match="core_normals"):
        m3c2kit.compare(ref, cmp, core, normal_source="core", projection_scale=0.3, max_depth=0.5)


def test_progress_callback_can_cancel():
    ref, cmp = noisy_plane_pair(n=60)
    # The package's own exception (an M3C2Error), not the binding's RuntimeError.
    with pytest.raises(m3c2kit.Cancelled, match="cancel") as caught:
        m3c2kit.compare(ref, cmp, progress=lambda done, total: False, **PARAMS)
    assert isinstance(caught.value, m3c2kit.M3C2Error)


def test_exception_in_progress_callback_propagates():
    ref, cmp = noisy_plane_pair(n=60)

    def boom(done, total):
        raise ZeroDivisionError("from the callback")

    with pytest.raises(ZeroDivisionError, match="from the callback"):
        m3c2kit.compare(ref, cmp, progress=boom, **PARAMS)


def test_output_columns_are_the_contract():
    ref, cmp = noisy_plane_pair(n=30)
    r = m3c2kit.compare(ref, cmp, **PARAMS)
    assert tuple(r.columns()) == m3c2kit.COLUMNS
    assert tuple(r.columns(projected=True))[-6:] == ("x1", "y1", "z1", "x2", "y2", "z2")
