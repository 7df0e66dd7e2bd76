"""TAM3C2 (include/m3c2/tam3c2.hpp; docs/series.md, "TAM3C2") against a brute-force numpy
implementation written here from the paper's definitions (tam3c2_readme.md of xyuhuang/py4dgeo:
nearest-in-time aggregation within W = gap x ratio until min_points, the most planar sphere's
normal, (weighted) means and spreads, Kish's effective n, the LOD), on tiny seeded series: the
same distances and LODs to 1e-9, for every weighting and several scales, and with our two
extensions (the fallback to the epoch's own M3C2, the window breaks at change points); the same
bits for any thread count."""
from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from m3c2kit import engine as facade


def segments(row, times, s):
    """The breaks' segment of each pool epoch (tam3c2.hpp, Tam3c2Breaks): the change points of the
    finite values of `row` in time order (the engine's change_points, tested on its own against
    ruptures), a NaN epoch in the segment of the finite epoch before it."""
    by_time = sorted(range(len(times)), key=lambda e: (times[e], e))
    finite = np.array([row[e] for e in by_time if np.isfinite(row[e])])
    starts = set()
    if len(finite) > s["break_width"]:
        starts = set(int(k) for k in facade.change_points(finite, s["break_width"], s["break_min_size"], 1,
                                                          s["break_penalty"]))
    out, current, k = np.zeros(len(times), dtype=int), 0, 0
    for e in by_time:
        if np.isfinite(row[e]):
            current += k in starts
            k += 1
        out[e] = current
    return out


def brute_force(clouds, times, core, ref, targets, s, epochwise=None):
    """TAM3C2 by exhaustive search: every point of every epoch tested (no spatial index)."""
    times = np.asarray(times, dtype=float)
    span = times.max() - times.min() or 1.0
    o = np.asarray(s["orientation"], dtype=float)
    segment = None

    def aggregate(c, centre_epoch, window, inside):
        centre = times[centre_epoch]
        order = sorted(range(len(times)), key=lambda e: (abs(times[e] - centre), e))
        pts, dts, epochs = [], [], 0
        for e in order:
            dt = times[e] - centre
            if abs(dt) > window:
                break
            if segment is not None and segment[e] != segment[centre_epoch]:
                continue  # the breaks: only the centre's segment
            found = clouds[e][inside(clouds[e] - c)]
            if len(found) == 0:
                continue
            pts.append(found), dts.append(np.full(len(found), dt))
            epochs += 1
            if sum(len(p) for p in pts) >= s["min_points"]:
                break
        if not pts:
            return np.zeros((0, 3)), np.zeros(0), 0
        return np.vstack(pts), np.concatenate(dts), epochs

    def weights(v, dt, n, window):
        if s["weights"] == "none":
            return None
        along = v @ n
        us = np.sqrt(np.maximum((v * v).sum(1) - along ** 2, 0)) / s["cylinder_radius"]
        win = window * s["space_time_ratio"]
        ut = np.abs(dt) / win
        sg = s["sigma_ratio"]
        if s["weights"] == "linear":
            w = np.clip(1 - us, 0, 1) * np.clip(1 - ut, 0, 1)
        else:
            w = np.exp(-us ** 2 / (2 * sg * sg)) * np.exp(-ut ** 2 / (2 * sg * sg))
        return w if (w > 0).any() else np.ones_like(w)

    def moments(p, w):
        if w is None:
            return p.mean(), p.std(ddof=1), float(len(p))
        m = (w * p).sum() / w.sum()
        return m, np.sqrt((w * (p - m) ** 2).sum() / w.sum()), max(w.sum() ** 2 / (w * w).sum(), 1.0)

    combos = [(r, q) for r in s["normal_radii"] for q in s["window_ratios"]]
    out = {k: np.full((len(core), len(targets)), np.nan) for k in ("distance", "lod", "n1", "n2", "significant")}
    for i, c in enumerate(core):
        if s.get("breaks", "none") == "changepoints":
            segment = segments(epochwise["distance"][i], times, s)
        best, normal, ratio = -np.inf, o, combos[0][1]
        for r, q in combos:
            pts, _, _ = aggregate(c, ref, span * q, lambda v: (v * v).sum(1) <= r * r)
            if len(pts) < 3:
                continue
            lam, vec = np.linalg.eigh(np.cov(pts.T, bias=True))
            pl = (lam[1] - lam[0]) / lam[2] if lam[2] > 1e-12 else 0.0
            if pl > best:
                best, normal, ratio = pl, vec[:, 0] * (1 if vec[:, 0] @ o >= 0 else -1), q
        cyl = lambda v: ((v * v).sum(1) - (v @ normal) ** 2 <= s["cylinder_radius"] ** 2) & (
            np.abs(v @ normal) <= s["max_distance"])
        for j, t in enumerate(targets):
            window = (abs(times[t] - times[ref]) or span) * ratio
            p1, d1, _ = aggregate(c, ref, window, cyl)
            p2, d2, _ = aggregate(c, t, window, cyl)
            short = min(len(p1), len(p2)) < max(s["min_points"], 2)
            if s.get("fallback", "none") == "m3c2" and short and np.isfinite(epochwise["distance"][i, t]):
                for k in out:  # the epoch's own M3C2
                    out[k][i, j] = epochwise[k][i, t]
                continue
            if len(p1) < 2 or len(p2) < 2:
                continue
            w1, w2 = weights(p1 - c, d1, normal, window), weights(p2 - c, d2, normal, window)
            m1, s1, n1 = moments((p1 - c) @ normal, w1)
            m2, s2, n2 = moments((p2 - c) @ normal, w2)
            out["distance"][i, j] = m2 - m1
            out["lod"][i, j] = lod(s, s1, n1, w1 is not None, s2, n2, w2 is not None)
            out["n1"][i, j], out["n2"][i, j] = n1, n2
            out["significant"][i, j] = abs(m2 - m1) > out["lod"][i, j]
    return out


def lod(s, s1, n1, weighted1, s2, n2, weighted2):
    """The LOD of two sides: the reference's z formula, or (lod t, auto) Welch's t at the sides'
    (effective) n with the weighted spreads made unbiased (reliability weights), from scipy's t."""
    statistic = s.get("lod", "z")
    if statistic != "z":  # a side of effective n 1 (one point's weight) bounds nothing
        s1 = (s1 * np.sqrt(n1 / (n1 - 1)) if n1 > 1 else np.inf) if weighted1 else s1
        s2 = (s2 * np.sqrt(n2 / (n2 - 1)) if n2 > 1 else np.inf) if weighted2 else s2
    v1, v2 = s1 ** 2 / n1, s2 ** 2 / n2
    critical = stats.norm.ppf(0.5 + s.get("confidence", 0.95) / 2)
    if statistic == "t" or (statistic == "auto" and min(n1, n2) < 30):
        with np.errstate(divide="ignore", invalid="ignore"):
            dof = (v1 + v2) ** 2 / (v1 ** 2 / (n1 - 1) + v2 ** 2 / (n2 - 1))  # Welch-Satterthwaite
        critical = stats.t.ppf(0.5 + s.get("confidence", 0.95) / 2, dof) if np.isfinite(dof) and dof > 0 else np.inf
    return critical * np.sqrt(v1 + v2) + s["registration_error"]


def tiny_series(seed: int, epochs: int = 7):
    """A tilted rough plane rising 3 cm per day, epochs of very different density, irregular times."""
    rng = np.random.default_rng(seed)
    times = np.cumsum(rng.uniform(0.5, 3.0, epochs))
    clouds = []
    for e, t in enumerate(times):
        n = int(rng.choice([15, 60, 200]))
        x, y = rng.uniform(-2, 2, n), rng.uniform(-2, 2, n)
        z = 0.2 * x - 0.1 * y + 0.03 * t + 0.05 * np.sin(3 * x) + rng.normal(0, 0.01, n)
        clouds.append(np.column_stack([x, y, z]))
    core = np.column_stack([rng.uniform(-1.2, 1.2, 25), rng.uniform(-1.2, 1.2, 25), np.zeros(25)])
    return clouds, times, core


def settings(**kw):
    s = dict(normal_radii=[0.5, 1.0], window_ratios=[0.3, 1.0], min_points=12, cylinder_radius=0.35,
             max_distance=1.0, weights="none", sigma_ratio=1.0, space_time_ratio=1.0, registration_error=0.005,
             orientation=[0.0, 0.0, 1.0])
    s.update(kw)
    return s


@pytest.mark.parametrize("statistic", ["z", "t", "auto"])
@pytest.mark.parametrize("weights", ["none", "linear", "gaussian"])
@pytest.mark.parametrize("seed", [1, 2])
def test_the_engine_equals_a_brute_force_tam3c2(seed, weights, statistic):
    clouds, times, core = tiny_series(seed)
    s = settings(weights=weights, space_time_ratio=1.5 if weights == "gaussian" else 1.0, lod=statistic,
                 confidence=0.9 if statistic == "t" else 0.95)
    ref, targets = 2, [0, 1, 3, 4, 5, 6, 2]  # the reference's own time too (the whole span as window)
    pool = facade.tam3c2_pool(clouds, times)
    got = facade.tam3c2(pool, core, ref, targets, s, threads=1)
    want = brute_force(clouds, times, core, ref, targets, s)
    for key in ("distance", "lod", "n1", "n2"):
        assert np.array_equal(np.isnan(got[key]), np.isnan(want[key])), key
        # the LOD also relatively: at a fraction of a degree of freedom t's quantile is astronomical
        # (1e97), and boost's and scipy's agree there to 1e-12 of it
        np.testing.assert_allclose(got[key], want[key], rtol=1e-9 if key == "lod" else 0, atol=1e-9, err_msg=key)
    assert np.isfinite(got["distance"]).sum() > 0.3 * got["distance"].size  # a test that compares numbers


def _epochwise(times, ref, cores: int, seed: int):
    """Stand-in per-epoch M3C2 (the engine only reads it): the rise, a step of 8 cm from the 7th
    epoch on, noise, and 15 % of the cells without a distance; the reference's own 0."""
    rng = np.random.default_rng(seed + 100)
    n = len(times)
    d = 0.03 * (times - times[ref]) + np.where(np.arange(n) >= 6, 0.08, 0.0) + rng.normal(0, 0.005, (cores, n))
    d[rng.random((cores, n)) < 0.15] = np.nan
    d[:, ref] = 0.0
    none = np.isnan(d)
    m = {"distance": d, "lod": rng.uniform(0.01, 0.05, (cores, n)), "significant": rng.integers(0, 2, (cores, n)) * 1.0,
         "n1": rng.integers(10, 40, (cores, n)) * 1.0, "n2": rng.integers(2, 20, (cores, n)) * 1.0}
    for k in ("lod", "significant", "n1", "n2"):
        m[k][none] = np.nan
    return m


@pytest.mark.parametrize("fallback", ["none", "m3c2"])
@pytest.mark.parametrize("breaks", ["none", "changepoints"])
@pytest.mark.parametrize("seed", [1, 2])
def test_the_extensions_equal_a_brute_force_tam3c2(seed, breaks, fallback):
    """The fallback (a cell short of min_points takes the epoch's own M3C2 where it has one) and
    the breaks (each side only in its centre's segment) against the brute force; each changes
    cells (else this test could not fail)."""
    clouds, times, core = tiny_series(seed, epochs=10)
    ref, targets = 2, [0, 1, 3, 4, 5, 6, 7, 8, 9]
    m = _epochwise(times, ref, len(core), seed)
    s = settings(fallback=fallback, breaks=breaks, break_width=4, break_min_size=2, break_penalty=0.05, lod="t")
    pool = facade.tam3c2_pool(clouds, times)
    got = facade.tam3c2(pool, core, ref, targets, s, epochwise=m, threads=1)
    want = brute_force(clouds, times, core, ref, targets, s, epochwise=m)
    for key in ("distance", "lod", "n1", "n2", "significant"):
        assert np.array_equal(np.isnan(got[key] if key != "significant" else np.where(got[key] < 0, np.nan, 0)),
                              np.isnan(want[key])), key
        w = want[key] if key != "significant" else np.where(np.isnan(want[key]), -1, want[key])
        np.testing.assert_allclose(got[key], w, rtol=1e-9 if key == "lod" else 0, atol=1e-9, err_msg=key)
    assert (got["source"] == facade.TAM3C2_SOURCE_EPOCH).any() == (fallback == "m3c2")
    if breaks == "changepoints":
        unbroken = facade.tam3c2(pool, core, ref, targets, dict(s, breaks="none"), epochwise=m, threads=1)
        assert not np.array_equal(got["distance"], unbroken["distance"], equal_nan=True)


def test_the_window_cap_and_min_points_change_the_result():
    """Sensitivity: a smaller cap borrows fewer epochs (more NaN), a larger min_points borrows more."""
    clouds, times, core = tiny_series(3)
    pool = facade.tam3c2_pool(clouds, times)
    wide = facade.tam3c2(pool, core, 0, range(1, 7), settings(window_ratios=[1.0]))
    narrow = facade.tam3c2(pool, core, 0, range(1, 7), settings(window_ratios=[0.01]))
    assert np.isfinite(wide["distance"]).sum() > np.isfinite(narrow["distance"]).sum()
    assert (wide["epochs2"] >= narrow["epochs2"]).all() and (wide["epochs2"] > narrow["epochs2"]).any()
    more = facade.tam3c2(pool, core, 0, range(1, 7), settings(window_ratios=[1.0], min_points=40))
    assert more["points2"].sum() > wide["points2"].sum()  # (min_points also moves the normal's contest)


@pytest.mark.parametrize("extended", [False, True])
def test_the_same_bits_for_any_thread_count(extended):
    clouds, times, core = tiny_series(4, epochs=9)
    pool = facade.tam3c2_pool(clouds, times)
    s = settings(weights="gaussian")
    m = None
    if extended:  # the fallback and the breaks
        s.update(fallback="m3c2", breaks="changepoints", break_width=4, break_min_size=2)
        m = _epochwise(times, 0, len(core), 4)
    a = facade.tam3c2(pool, core, 0, range(9), s, epochwise=m, threads=1)
    b = facade.tam3c2(pool, core, 0, range(9), s, epochwise=m, threads=3)
    for key in a:
        assert a[key].tobytes() == b[key].tobytes(), key


def test_a_tie_in_time_distance_borrows_the_earlier_epoch():
    """Epochs 1 h before and after the target are equally near: the earlier one is taken."""
    g = np.linspace(-0.5, 0.5, 11)
    plane = lambda z: np.column_stack([np.repeat(g, 11), np.tile(g, 11), np.full(121, z)])  # noqa: E731
    clouds = [plane(0.0), plane(0.1), np.array([[0.0, 0.0, 0.2]]), plane(0.3)]
    pool = facade.tam3c2_pool(clouds, [0.0, 4.0, 5.0, 6.0])
    s = settings(normal_radii=[0.5], window_ratios=[1.0], min_points=5, cylinder_radius=0.25, weights="none")
    r = facade.tam3c2(pool, np.zeros((1, 3)), 0, [2], s)
    assert r["epochs2"][0, 0] == 2
    k = r["points2"][0, 0] - 1  # the plane's points besides the target's one
    assert abs(r["distance"][0, 0] - (0.2 + 0.1 * k) / (k + 1)) < 1e-12


def _stable_series(seed: int = 5, epochs: int = 12):
    """No change: a tilted plane with iid noise (1 cm), a dense reference and sparse epochs at
    irregular hours; core points every 0.3 m."""
    rng = np.random.default_rng(seed)
    hours = np.cumsum(rng.integers(1, 6, epochs)).astype(float)
    clouds = []
    for k in range(epochs):
        n = 3000 if k == 0 else int(rng.choice([150, 400, 1500]))
        x, y = rng.uniform(0, 10, n), rng.uniform(0, 10, n)
        clouds.append(np.column_stack([x, y, 0.1 * x + rng.normal(0, 0.01, n)]))
    g = np.arange(0.6, 9.4, 0.3)
    return clouds, hours / 24.0, np.array([(a, b, 0.1 * a) for a in g for b in g])


@pytest.mark.parametrize("weights", ["none", "linear"])
def test_on_unchanged_surfaces_t_and_auto_flag_about_five_percent_and_z_too_many(weights):
    """Calibration (docs/series.md, "TAM3C2", Calibration): at 95 %, with sides of about
    --required-points 10 points, the reference's z flags 10-16 % of unchanged cells; Welch's t
    (and the paper's auto rule) with the weighted spreads made unbiased flags about 5 %."""
    clouds, days, core = _stable_series()
    pool = facade.tam3c2_pool(clouds, days)
    rates = {}
    for statistic in ("z", "t", "auto"):
        s = settings(weights=weights, window_ratios=[0.2], min_points=10, cylinder_radius=0.3, registration_error=0.0,
                     confidence=0.95, lod=statistic)
        r = facade.tam3c2(pool, core, 0, range(1, len(clouds)), s)
        ok = np.isfinite(r["distance"])
        assert ok.sum() > 7000
        rates[statistic] = float((np.abs(r["distance"][ok]) > r["lod"][ok]).mean())
    assert rates["z"] > 0.09, rates
    assert 0.03 < rates["t"] < 0.065 and 0.03 < rates["auto"] < 0.065, rates
