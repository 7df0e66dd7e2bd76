"""The error model file (m3c2kit.analysis.error_model): round trip, every field checked on load,
version 1 files read and refused by compare, the excess variance, the conventions of the two
kinds, and the disc-distance pdf against a Monte Carlo."""
import json
import re

import numpy as np
import pytest

from m3c2kit.analysis.error_model import (Component, ErrorModel, ErrorModelError, disc_distance_pdf, for_compare,
                                          load, save)
from m3c2kit.base.errors import UsageError

MODEL = ErrorModel(1e-5, (Component("spherical", 4e-5, 3.0), Component("exponential", 2e-5, 20.0)), 1.0, "3d",
                   "test", ((0.5, 1e-5, 10), (2.0, 4e-5, 30)), mean_u2=3e-5)


def test_round_trip(tmp_path):
    save(tmp_path / "m.json", MODEL)
    back = load(tmp_path / "m.json")
    assert back == MODEL and back.empirical == MODEL.empirical
    assert back.correlated_variance() == pytest.approx(6e-5)
    doc = json.loads((tmp_path / "m.json").read_text())
    assert doc["version"] == 2 and doc["mean_u2"] == 3e-5 and doc["excess_variance"] == pytest.approx(4e-5)


def test_excess_variance():
    # total sill 1e-5 + 6e-5, minus eq. (1)'s mean u^2: what eq. (1) does not count; never negative
    assert MODEL.total_variance() == pytest.approx(7e-5)
    assert MODEL.excess_variance() == pytest.approx(4e-5, rel=1e-12)
    assert ErrorModel(1e-5, MODEL.components, mean_u2=9e-5).excess_variance() == 0.0
    # the nugget beyond eq. (1)'s u^2 is excess too (correlation shorter than the core spacing)
    assert ErrorModel(5e-5, (), mean_u2=2e-5).excess_variance() == pytest.approx(3e-5)
    with pytest.raises(ValueError, match="mean_u2"):
        ErrorModel(0.0, MODEL.components).excess_variance()


def test_version_1_is_read_and_refused_by_compare(tmp_path):
    doc = {"format": "m3c2kit-error-model", "version": 1, "nugget": 1e-5, "projection_scale": 1.0,
           "components": [{"kind": "spherical", "sill": 4e-5, "range": 3.0}]}
    path = tmp_path / "v1.json"
    path.write_text(json.dumps(doc))
    model = load(path)  # its components still serve the covariance between core points
    assert model.mean_u2 is None and model.covariance(0.0) == pytest.approx(4e-5)
    with pytest.raises(ErrorModelError, match="no 'mean_u2'.*refit the model with m3c2 variogram") as e:
        for_compare(path)
    assert str(e.value).startswith(str(path))
    from m3c2kit.settings import build_params
    with pytest.raises(UsageError, match="v1.json: the error model has no 'mean_u2'"):
        build_params(projection_scale=1.0, max_depth=1.0, normal_scale=1.0, error_model=str(path))
    save(tmp_path / "v2.json", ErrorModel(1e-5, MODEL.components, 1.0, mean_u2=3e-5))
    assert build_params(projection_scale=1.0, max_depth=1.0, normal_scale=1.0,
                        error_model=str(tmp_path / "v2.json")).correlated_variance == pytest.approx(4e-5)


def test_conventions():
    s, e = Component("spherical", 2.0, 5.0), Component("exponential", 2.0, 5.0)
    assert s.variogram(5.0) == 2.0 and s.variogram(10.0) == 2.0 and s.variogram(2.5) == pytest.approx(2 * (0.75 - 0.0625))
    assert e.variogram(5.0) == pytest.approx(0.95 * 2.0, rel=3e-3)  # the practical range: 95 % of the sill
    assert MODEL.variogram(0.0) == 0.0
    assert MODEL.variogram(1e-9) == pytest.approx(1e-5, rel=1e-3)  # the nugget at any lag > 0
    assert MODEL.covariance(0.0) == pytest.approx(6e-5)  # the correlated part only
    assert MODEL.covariance(1e6) == pytest.approx(0.0, abs=1e-15)


def test_disc_pdf_against_monte_carlo():
    rng = np.random.default_rng(4)
    r = np.sqrt(rng.uniform(0, 1, (200000, 2))) * 0.5
    a = rng.uniform(0, 2 * np.pi, (200000, 2))
    p = np.stack([r * np.cos(a), r * np.sin(a)], -1)
    dist = np.linalg.norm(p[:, 0] - p[:, 1], axis=1)
    hist, edges = np.histogram(dist, bins=20, range=(0, 1), density=True)
    mid = 0.5 * (edges[1:] + edges[:-1])
    assert np.allclose(hist, disc_distance_pdf(mid, 1.0), atol=0.05)
    # the variance of the disc mean of the correlated part: against the Monte Carlo of the pairs
    m = ErrorModel(0.0, (Component("spherical", 1.0, 2.0),))
    assert m.disc_mean_variance(1.0) == pytest.approx(np.mean(m.covariance(dist)), rel=5e-3)


@pytest.mark.parametrize("doc, words", [
    ({"format": "x"}, "not an error model file"),
    ({"format": "m3c2kit-error-model", "version": 3}, "version 3"),
    ({"format": "m3c2kit-error-model", "version": True}, "version True"),
    ({"format": "m3c2kit-error-model", "version": 2, "nugget": 0, "mean_u2": -1,
      "components": [{"kind": "spherical", "sill": 1, "range": 1}]}, "'mean_u2'"),
    ({"format": "m3c2kit-error-model", "version": 2, "nugget": 0, "mean_u2": 0.5,
      "components": [{"kind": "spherical", "sill": 1, "range": 1}]}, "'excess_variance'"),
    ({"format": "m3c2kit-error-model", "version": 2, "nugget": 0, "mean_u2": 0.5, "excess_variance": 0.6,
      "components": [{"kind": "spherical", "sill": 1, "range": 1}]}, "is not max(0, nugget + sills - mean_u2)"),
    ({"format": "m3c2kit-error-model", "version": 1, "nugget": -1, "components": []}, "'nugget'"),
    ({"format": "m3c2kit-error-model", "version": 1, "nugget": 0, "components": []}, "'components'"),
    ({"format": "m3c2kit-error-model", "version": 1, "nugget": 0,
      "components": [{"kind": "gaussian", "sill": 1, "range": 1}]}, "component 0"),
    ({"format": "m3c2kit-error-model", "version": 1, "nugget": 0,
      "components": [{"kind": "spherical", "sill": 1, "range": 0}]}, "'range'"),
    ({"format": "m3c2kit-error-model", "version": 1, "nugget": 0, "projection_scale": "1",
      "components": [{"kind": "spherical", "sill": 1, "range": 1}]}, "'projection_scale'"),
    ({"format": "m3c2kit-error-model", "version": 1, "nugget": 0, "lag_distance": "1d",
      "components": [{"kind": "spherical", "sill": 1, "range": 1}]}, "'lag_distance'"),
])
def test_load_refuses(tmp_path, doc, words):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(ErrorModelError, match=str(path).replace(".", r"\.")) as e:
        load(path)
    assert words in str(e.value) and isinstance(e.value, UsageError)


def test_load_refuses_non_json_and_missing(tmp_path):
    (tmp_path / "t.json").write_text("{")
    with pytest.raises(ErrorModelError, match="not valid JSON"):
        load(tmp_path / "t.json")
    with pytest.raises(ErrorModelError, match="missing.json"):
        load(tmp_path / "missing.json")


@pytest.mark.parametrize("kind", ["spherical", "exponential"])
def test_the_components_formulas_are_the_engines_and_the_analytic_ones(kind):
    """One owner (issue 41): Component.covariance/.variogram are the engine's C(h) and gamma(h)
    (include/m3c2/region_covariance.hpp, also what the region sums use), checked against the
    closed forms; gamma keeps its digits near h = 0, where the fit looks."""
    from m3c2kit.engine import component_values
    c = Component(kind, 2.5, 4.0)
    h = np.array([[0.0, 1e-9, 0.3], [3.999, 4.0, 9.0]])
    r = h / 4.0
    if kind == "spherical":
        gamma = np.where(r < 1, 2.5 * (1.5 * r - 0.5 * r ** 3), 2.5)
    else:
        gamma = 2.5 * (1 - np.exp(-3 * r))
    np.testing.assert_allclose(c.variogram(h), gamma, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(c.covariance(h), 2.5 - gamma, rtol=1e-12, atol=1e-15)
    assert c.variogram(h).shape == h.shape
    np.testing.assert_allclose(c.variogram(1e-9), 2.5 * 3 * 1e-9 / 4 * (0.5 if kind == "spherical" else 1), rtol=1e-6)
    np.testing.assert_array_equal(c.covariance(h), component_values(kind, 2.5, 4.0, h))


@pytest.mark.parametrize("change, words", [
    (lambda d: d["components"][0].update(sill=1e308), "'sill' must be a number from 0 to 1e+100, found 1e+308"),
    (lambda d: d["components"][0].update(range=1e-300), "'range' must be a number from 1e-100 to 1e+100, found 1e-300"),
    (lambda d: d.update(nugget=1e200), "'nugget' must be a number from 0 to 1e+100"),
])
def test_numbers_that_overflow_the_intervals_are_refused(tmp_path, change, words):
    """Hostile round 2: a sill of 1e308 gave NaN intervals with exit 0 (the region sums and the
    fields' FFTs overflowed); a range of 1e-300 asked for a grid of 1e300 cells."""
    save(tmp_path / "m.json", MODEL)
    doc = json.loads((tmp_path / "m.json").read_text())
    change(doc)
    (tmp_path / "m.json").write_text(json.dumps(doc))
    with pytest.raises(ErrorModelError, match=re.escape(words)):
        load(tmp_path / "m.json")


def test_a_field_too_fine_for_its_box_is_refused_at_once():
    """The grid's size is checked in floats before any FFT length is sought (a tiny range's cell
    count overflowed int64, and the search for a fast length took minutes)."""
    from m3c2kit.analysis.random_fields import sample_field
    xy = np.array([[0.0, 0.0], [10.0, 10.0]])
    with pytest.raises(UsageError, match=r"needs 3.2e\+102 x 3.2e\+102 grid cells, more than"):
        sample_field(xy, ErrorModel(0.0, (Component("spherical", 1.0, 1e-100),)), 0)
