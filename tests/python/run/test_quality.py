"""The diagnoses behind the data-quality warnings (m3c2kit.run.quality): no overlap vs. a depth too
short, normals that fail because D was given as a radius, shares over what they describe."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import m3c2kit
from m3c2kit import engine
from m3c2kit.run import in_memory
from m3c2kit.run import quality as Q
from m3c2kit.io.arrays import bounds

TORONTO = Path(__file__).resolve().parents[3] / "data" / "toronto-ttp"


@pytest.fixture(scope="module")
def toronto():
    return m3c2kit.read(TORONTO / "TTP_15.laz").xyz, m3c2kit.read(TORONTO / "TTP_23.laz").xyz


def _no_compared_point_on_the_line(cmp_xyz, core, normal, radius) -> bool:
    """Oracle: no compared point within `radius` of the infinite line core + t normal."""
    rel = cmp_xyz - core
    along = rel @ normal
    perp2 = np.einsum("ij,ij->i", rel, rel) - along**2
    return not np.any(perp2 <= radius**2)


@pytest.mark.parametrize("cloud", [1, 2])
def test_the_one_cloud_index_gives_the_two_cloud_runs_cylinders(toronto, cloud):
    # The diagnosis indexes only the cloud it reads (engine.CylinderIndex), once for both of its
    # diameters: its counts, offsets and spreads must be those of a run on both clouds (exactly at
    # the index's own diameter; the wider cylinder's sums in another key order, so to rounding),
    # and it has an offset wherever it found points (the two-cloud run has none where the other
    # cloud's cylinder is empty too).
    ref, cmp_ = toronto
    core = ref[::7] + np.array([0.0, 0.0, 30.0]) if cloud == 1 else ref[::7]  # lifted: empty in the reference
    r = m3c2kit.compare(ref, cmp_, core, projection_scale=1, max_depth=5, normal_source="vertical")
    idx = np.flatnonzero(r.status == Q._EMPTY[cloud])
    assert idx.size > 100
    reach = 200.0
    points = ref if cloud == 1 else cmp_
    index = engine.CylinderIndex(points, 1.0)
    for diameter in (1.0, 4.0):
        kw = dict(normal_source="core", core_normals=r.normal[idx], projection_scale=diameter, max_depth=reach,
                  min_points=1)
        both = in_memory.compare(ref, cmp_, r.core[idx], warn=False, **kw)
        alone = index.statistics(r.core[idx], r.normal[idx], diameter, reach)
        n, offset = (both.n1, both.i1) if cloud == 1 else (both.n2, both.i2)
        sigma = both.sigma1 if cloud == 1 else both.sigma2
        assert np.array_equal(alone["count"], n) and (n > 0).sum() > 10
        found, both_found = n > 0, np.isfinite(offset)
        assert np.isfinite(alone["mean"][found]).all() and both_found.sum() > 10
        assert np.isnan(alone["mean"][~found]).all()
        same = np.array_equal if diameter == 1.0 else lambda a, b, **kw: np.allclose(a, b, rtol=1e-12, atol=1e-9, **kw)
        assert same(alone["mean"][both_found], offset[both_found])
        assert same(alone["sigma"][both_found], sigma[both_found], equal_nan=True)  # NaN: one point, no spread


def test_both_clouds_diagnosed_alike_on_one_thread_and_two(toronto):
    # The diagnosis's engine runs index each cloud on the run's threads (the parallel build):
    # the same diagnoses on one thread and on two (core points lifted 30 m: empty in the
    # reference; the shoreline: empty in the compared cloud).
    ref, cmp_ = toronto
    core = np.concatenate([ref[::7], ref[::11] + np.array([0.0, 0.0, 30.0])])
    r = m3c2kit.compare(ref, cmp_, core, projection_scale=1, max_depth=5, normal_source="vertical")
    runs = [Q.cylinder_diagnosis(ref, cmp_, r, projection_scale=1, max_depth=5, threads=t, at_most=500) for t in (1, 2)]
    assert [d.cloud for d in runs[0]] == [1, 2]
    for one, two in zip(*runs):
        for field in ("cloud", "with_normal", "empty", "needed_depth", "needed_scale", "diagnosed"):
            assert getattr(one, field) == getattr(two, field), field
        for field in ("no_overlap", "beyond_depth", "too_thin"):
            assert np.array_equal(getattr(one, field), getattr(two, field)), field
    assert runs[0][0].beyond_depth.size > 0 and runs[0][1].no_overlap.size > 0  # lifted; the shoreline


def test_bounds_are_numpys_column_minima_and_maxima():
    rng = np.random.default_rng(3)
    for xyz in (rng.normal(size=(1000, 3)), rng.normal(size=(5, 2)), np.array([[1.0, np.nan, 2.0], [0.0, 1.0, 3.0]])):
        lo, hi = bounds(xyz)
        assert np.array_equal(lo, xyz.min(axis=0), equal_nan=True) and np.array_equal(hi, xyz.max(axis=0), equal_nan=True)


def test_toronto_shoreline_is_no_overlap_at_every_depth(toronto):
    ref, cmp_ = toronto
    counts = []
    for depth in (20, 100, 1000):
        r = m3c2kit.compare(ref, cmp_, core_spacing=8, normal_scale=10, projection_scale=5, max_depth=depth)
        diag = {d.cloud: d for d in Q.cylinder_diagnosis(ref, cmp_, r, projection_scale=5, max_depth=depth)}
        compared = diag[2]
        counts.append(compared.no_overlap.size)
        messages = Q.cylinder_messages(list(diag.values()), depth)
        overlap = [m for m in messages if "do not overlap" in m]
        assert len(overlap) == 1 and "cannot help" in overlap[0] and "of the" in overlap[0], messages
        # Never advise a larger depth for points no depth can reach.
        assert not any("reaches 95 %" in m for m in messages if "compared points only beyond" in m
                       and compared.beyond_depth.size == 0)
        # The oracle agrees on a sample of the no-overlap core points.
        for i in compared.no_overlap[:: max(1, compared.no_overlap.size // 25)]:
            assert _no_compared_point_on_the_line(cmp_, r.core[i], r.normal[i], 2.5)
    # The cause does not depend on the depth asked for.
    assert counts[0] == counts[1] == counts[2] > 0


def test_the_warnings_sample_estimates_the_full_diagnosis(toronto):
    # Every reference point a core point (W1): 19,099 empty compared cylinders; the warnings
    # diagnose WARNING_SAMPLE of them, evenly spaced, and say "about".
    ref, cmp_ = toronto
    r = m3c2kit.compare(ref, cmp_, ref, normal_scale=2, projection_scale=1, max_depth=5, min_points=1)
    (full,) = [d for d in Q.cylinder_diagnosis(ref, cmp_, r, projection_scale=1, max_depth=5) if d.cloud == 2]
    (part,) = [d for d in Q.cylinder_diagnosis(ref, cmp_, r, projection_scale=1, max_depth=5,
                                               at_most=Q.WARNING_SAMPLE) if d.cloud == 2]
    assert full.empty == part.empty > 5 * Q.WARNING_SAMPLE and part.diagnosed == Q.WARNING_SAMPLE
    assert not full.sampled and part.sampled
    for kind in ("no_overlap", "beyond_depth", "too_thin"):
        whole, sample = getattr(full, kind), getattr(part, kind)
        assert np.isin(sample, whole).all()  # the same verdict on each diagnosed core point
        assert full.estimate(whole) == whole.size
        # The estimate within 4 binomial standard errors of the full count.
        p = whole.size / full.empty
        sd = full.empty * np.sqrt(p * (1 - p) / Q.WARNING_SAMPLE)
        assert abs(part.estimate(sample) - whole.size) <= 4 * sd + 1, kind
    assert part.needed_scale == pytest.approx(full.needed_scale, rel=0.2)
    full_text, part_text = Q.cylinder_messages([full], 5), Q.cylinder_messages([part], 5)
    assert len(full_text) == len(part_text) == 3
    assert all(not m.startswith("about") for m in full_text) and all(m.startswith("about ") for m in part_text)


def test_depth_too_short_advises_the_depth_that_reaches():
    rng = np.random.default_rng(5)
    xy = rng.uniform(0, 20, (4000, 2))
    ref = np.column_stack([xy, 0.01 * rng.standard_normal(4000)])
    cmp_ = np.column_stack([xy[::-1], 6.0 + 0.01 * rng.standard_normal(4000)])
    r = m3c2kit.compare(ref, cmp_, ref[::40], normal_scale=3, projection_scale=2, max_depth=2)
    diag = Q.cylinder_diagnosis(ref, cmp_, r, projection_scale=2, max_depth=2)
    (d,) = [x for x in diag if x.cloud == 2]
    assert d.no_overlap.size == 0 and d.beyond_depth.size == d.empty > 0
    assert 6.0 <= d.needed_depth < 6.2
    messages = Q.cylinder_messages(diag, 2)
    assert len(messages) == 1 and "--max-depth 6.1 reaches 95 %" in messages[0] and "overlap" not in messages[0]


def test_sparse_cloud_is_a_thin_cylinder_not_a_missing_overlap():
    # Two overlapping flat surveys at about 1 point/m2, 0.3 m apart; d = 1 m holds 0.8 points on
    # average, so about 45 % of the cylinders are empty (Poisson) although both clouds cover
    # every core point: the advice is a larger projection scale, never "no overlap" or a depth.
    rng = np.random.default_rng(8)
    n = 6000
    ref = np.column_stack([rng.uniform(0, 80, (n, 2)), 0.01 * rng.standard_normal(n)])
    cmp_ = np.column_stack([rng.uniform(0, 80, (n, 2)), 0.3 + 0.01 * rng.standard_normal(n)])
    core = ref[(ref[:, 0] > 10) & (ref[:, 0] < 70) & (ref[:, 1] > 10) & (ref[:, 1] < 70)][::4]
    r = m3c2kit.compare(ref, cmp_, core, normal_scale=6, projection_scale=1, max_depth=2)
    diag = Q.cylinder_diagnosis(ref, cmp_, r, projection_scale=1, max_depth=2)
    d = {x.cloud: x for x in diag}[2]
    assert d.empty / d.with_normal > 0.3
    assert d.no_overlap.size == 0 and d.beyond_depth.size == 0 and d.too_thin.size == d.empty
    messages = Q.cylinder_messages(diag, 2)
    assert len(messages) == 1 and "between the points" in messages[0] and "overlap" not in messages[0], messages
    advised = float(messages[0].split("--projection-scale ")[1].split()[0])
    assert 3.0 <= advised <= 4.5  # 2 sqrt(10 / (pi * 0.94 points/m2)) = 3.7 m
    # The advice works: the median cylinder holds about ADVISED_POINTS, empty cylinders are rare.
    again = m3c2kit.compare(ref, cmp_, core, normal_scale=6, projection_scale=advised, max_depth=2)
    assert 8 <= np.median(again.n2) <= 14 and np.mean(again.n2 == 0) < 0.01


def test_normal_failures_name_the_diameter(toronto):
    ref, cmp_ = toronto
    r = m3c2kit.compare(ref, cmp_, core_spacing=8, normal_scale=1, projection_scale=5, max_depth=10)
    m = Q.normal_failure_message(r, 1)
    assert m is not None and "DIAMETER" in m and "did you give a radius?" in m and "--normal-scale 2" in m
    assert m.split(" (")[0].startswith(f"{np.isin(r.status, (1, 2)).sum():,} of the {len(r):,} core points")
    ok = m3c2kit.compare(ref, cmp_, core_spacing=8, normal_scale=10, projection_scale=5, max_depth=10)
    assert Q.normal_failure_message(ok, 10) is None


def test_degenerate_neighbourhoods_get_no_radius_advice():
    """Issue 42: 'did you give a radius?' at --normal-scale 1e15, where every neighbourhood holds
    every point and a larger D cannot help: points on a line have no normal at any scale."""
    t = np.linspace(0.0, 10.0, 400)
    line = np.c_[t, 0.5 * t, np.zeros_like(t)]
    r = m3c2kit.compare(line, line + [0, 0, 0.1], line[::40], normal_scale=4, projection_scale=1, max_depth=1)
    m = Q.normal_failure_message(r, 4)
    assert m is not None and "collinear or coincident" in m and "radius" not in m and "lie on a line" in m


def test_share_text():
    assert Q.share_text(1234, 5678, "core points with a normal") == "1,234 of the 5,678 core points with a normal (21.7 %)"


def test_status_in_is_membership_of_the_named_codes():
    """m3c2kit.engine.result.status_in against set membership, for every subset size and every code."""
    from m3c2kit.engine.result import STATUS_NAMES, status_in

    rng = np.random.default_rng(3)
    status = rng.integers(0, len(STATUS_NAMES), 5000).astype(np.uint8)
    for k in range(len(STATUS_NAMES) + 1):
        names = tuple(rng.choice(STATUS_NAMES, size=k, replace=False))
        codes = {STATUS_NAMES.index(n) for n in names}
        want = np.array([int(s) in codes for s in status])
        np.testing.assert_array_equal(status_in(status, names), want)
    assert status_in(status, ()).dtype == bool and not status_in(status, ()).any()


def test_scales_absurd_for_the_data_are_warned():
    """Issue 44: D and d far beyond the cloud's extent put the whole cloud in every cylinder and called
    every core point significant (289 of 289), without a word."""
    rng = np.random.default_rng(4)
    ref = np.c_[rng.uniform(0, 10, (3000, 2)), 0.01 * rng.normal(size=3000)]
    cmp_ = ref + [0, 0, 0.02]
    with pytest.warns(m3c2kit.M3C2Warning) as caught:
        r = m3c2kit.compare(ref, cmp_, core_spacing=2, normal_scale=100, projection_scale=100, max_depth=100)
    said = " ".join(str(w.message) for w in caught)
    assert "--normal-scale 100 exceeds the reference's extent" in said
    assert "--projection-scale 100 is over half the reference's extent" in said
    assert "--max-depth 100 exceeds the reference's extent" in said
    assert np.nanmean(r.significant) == 1.0  # what the warning is about: every core point significant
    assert Q.scale_messages(2.0, 1.0, 1.0, Q.extent_of(ref)) == []  # ordinary scales: nothing
    assert Q.scale_messages([1, 2, 30], None, None, 14.2)[0].startswith("--normal-scale 30 exceeds")
    assert Q.scale_messages(1.0, 1.0, 1.0, float("nan")) == []
