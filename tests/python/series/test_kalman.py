"""The Kalman filter and RTS smoother (include/m3c2/kalman.hpp, series/kalman.py; docs/series.md,
"Kalman filter") against oracles written here: an independent numpy filter and smoother, the batch
generalised least-squares (GLS) solution of the same linear-Gaussian model (the smoother's exact
equal), and seeded simulations with known truth (error, band coverage at the nominal rate, false
flags on stable points, the maximum-likelihood q). The store's step (atomic publication, resume
after `add`, kills) is in test_kalman_store.py."""
from __future__ import annotations

import math

import numpy as np
import pytest

from m3c2kit import engine
from m3c2kit.series import kalman as km

Z95 = 1.959963984540054


def transition(k, dt):
    f = np.eye(k)
    f[0, 1] = dt
    if k == 3:
        f[0, 2], f[1, 2] = dt * dt / 2, dt
    return f


def noise_matrix(k, dt, noise):
    if noise == "discrete":
        g = np.array([dt * dt / 2, dt, 1.0][:k]) if k == 3 else np.array([dt * dt / 2, dt])
        return np.outer(g, g)
    if k == 2:
        return np.array([[dt ** 3 / 3, dt ** 2 / 2], [dt ** 2 / 2, dt]])
    return np.array([[dt ** 5 / 20, dt ** 4 / 8, dt ** 3 / 6], [dt ** 4 / 8, dt ** 3 / 3, dt ** 2 / 2],
                     [dt ** 3 / 6, dt ** 2 / 2, dt]])


def numpy_smoother(z, r, t, k, q, noise, v0=(0.0, 1.0, 1.0)):
    """The textbook filter (standard covariance update, explicit inverse) and RTS smoother of one
    series, started at its first observation: an implementation independent of the engine's."""
    n = len(z)
    xf, pf = [None] * n, [None] * n
    x = p = None
    t_last = None
    ll = 0.0
    for i in range(n):
        ok = np.isfinite(z[i]) and np.isfinite(r[i])
        if x is None:
            if not ok:
                continue
            x = np.zeros(k)
            x[0] = z[i]
            p = np.diag([r[i], *v0[1:k]])
        else:
            f = transition(k, t[i] - t_last)
            x = f @ x
            p = f @ p @ f.T + q * noise_matrix(k, t[i] - t_last, noise)
            if ok:
                s = p[0, 0] + r[i]
                gain = p[:, 0] / s
                innov = z[i] - x[0]
                ll += -0.5 * (math.log(2 * math.pi * s) + innov * innov / s)
                x = x + gain * innov
                p = p - np.outer(gain, p[0, :])
        t_last = t[i]
        xf[i], pf[i] = x.copy(), p.copy()
    mean, sd = np.full((n, k), np.nan), np.full((n, k), np.nan)
    if x is None:
        return mean, sd, ll
    xs, ps = xf[-1], pf[-1]
    mean[-1], sd[-1] = xs, np.sqrt(np.diag(ps))
    for i in range(n - 2, -1, -1):
        if xf[i] is None:
            break
        dt = t[i + 1] - t[i]
        f = transition(k, dt)
        pp = f @ pf[i] @ f.T + q * noise_matrix(k, dt, noise)
        c = pf[i] @ f.T @ np.linalg.inv(pp)
        xs = xf[i] + c @ (xs - f @ xf[i])
        ps = pf[i] + c @ (ps - pp) @ c.T
        mean[i], sd[i] = xs, np.sqrt(np.diag(ps))
    return mean, sd, ll


def engine_smoother(z, r, t, model, q, noise, threads=1):
    k = km.MODELS[model]
    z, r = np.atleast_2d(z).astype(float), np.atleast_2d(r).astype(float)
    moments = np.full((*z.shape, k + k * (k + 1) // 2), np.nan)
    p = km._kalman_params(model, noise, q)
    return engine.kalman_smooth(np.ascontiguousarray(z), np.ascontiguousarray(r), np.asarray(t, float), moments, p,
                                threads=threads)


def series(rng, n, missing=0.15):
    t = np.cumsum(rng.uniform(0.2, 2.0, n)) - 0.5
    truth = 0.05 * t + 0.3 * np.sin(t / 3)
    r = rng.uniform(0.01, 0.05, n) ** 2
    z = truth + rng.normal(0, np.sqrt(r))
    z[rng.random(n) < missing] = np.nan
    z[0] = np.nan  # the filter starts at the first observation, later than the first epoch
    return z, r, t


@pytest.mark.parametrize("model", ["velocity", "acceleration"])
@pytest.mark.parametrize("noise", ["continuous", "discrete"])
def test_the_filter_and_smoother_equal_an_independent_numpy_one(model, noise):
    rng = np.random.default_rng(3)
    k = km.MODELS[model]
    for trial in range(5):
        z, r, t = series(rng, 30)
        q = 10.0 ** rng.uniform(-5, -1)
        ours = engine_smoother(z, r, t, model, q, noise)
        mean, sd, ll = numpy_smoother(z, r, t, k, q, noise)
        np.testing.assert_allclose(ours["mean"][0], mean, rtol=0, atol=1e-9)
        np.testing.assert_allclose(ours["sd"][0], sd, rtol=0, atol=1e-9)
        assert ours["log_likelihood"][0] == pytest.approx(ll, abs=1e-8)
        assert np.isnan(ours["mean"][0, 0]).all()  # before the first observation: no estimate


def gls(z, r, t, k, q, v0=(0.0, 1.0, 1.0)):
    """The batch generalised least-squares estimate of the stacked states x_j (from the first
    observed epoch on) of the model the filter assumes: observations z_j = d_j + e_j (var r_j),
    dynamics x_{j+1} = F x_j + w_j (cov q M(dt)), prior rate (and acceleration) N(0, v0) at the
    start; its mean and covariance are those of the fixed-interval smoother (Rauch et al. 1965)."""
    first = int(np.flatnonzero(np.isfinite(z))[0])
    idx = list(range(first, len(z)))
    m = len(idx) * k
    info, b = np.zeros((m, m)), np.zeros(m)
    for j, e in enumerate(idx):
        if np.isfinite(z[e]):
            info[j * k, j * k] += 1 / r[e]
            b[j * k] += z[e] / r[e]
    for i in range(1, k):
        info[i, i] += 1 / v0[i]
    for j in range(len(idx) - 1):
        dt = t[idx[j + 1]] - t[idx[j]]
        f, qi = transition(k, dt), np.linalg.inv(q * noise_matrix(k, dt, "continuous"))
        a = np.zeros((k, m))
        a[:, j * k:(j + 1) * k] = -f
        a[:, (j + 1) * k:(j + 2) * k] = np.eye(k)
        info += a.T @ qi @ a
    cov = np.linalg.inv(info)
    mean = cov @ b
    return first, mean.reshape(-1, k), np.sqrt(np.diag(cov)).reshape(-1, k)


@pytest.mark.parametrize("model", ["velocity", "acceleration"])
def test_the_smoother_is_the_batch_least_squares_solution(model):
    rng = np.random.default_rng(5)
    k = km.MODELS[model]
    for trial in range(4):
        z, r, t = series(rng, 8, missing=0.2)
        q = 10.0 ** rng.uniform(-3, -1)
        ours = engine_smoother(z, r, t, model, q, "continuous")
        first, mean, sd = gls(z, r, t, k, q)
        np.testing.assert_allclose(ours["mean"][0, first:], mean, rtol=0, atol=1e-9)
        np.testing.assert_allclose(ours["sd"][0, first:], sd, rtol=0, atol=1e-9)


def simulate(rng, n_core, t, q, r):
    """Truth drawn from the velocity model itself (continuous white acceleration of density q),
    a third of the core points stable (d = 0 throughout), observed with variances r."""
    n = len(t)
    truth = np.zeros((n_core, n))
    moving = rng.random(n_core) > 1 / 3
    for c in np.flatnonzero(moving):
        x = np.array([0.0, rng.normal(0, 0.01)])
        truth[c, 0] = x[0]
        for i in range(1, n):
            dt = t[i] - t[i - 1]
            x = transition(2, dt) @ x + rng.multivariate_normal(np.zeros(2), q * noise_matrix(2, dt, "continuous"))
            truth[c, i] = x[0]
    z = truth + rng.normal(0, np.sqrt(r))
    return truth, z, moving


@pytest.mark.slow
def test_simulation_with_known_truth():
    """The smoothed change's error well below raw M3C2's; its 95 % bands covering the truth at the
    nominal rate (one epoch per core point: independent trials, a binomial interval); stable
    points flagged at most 5 %; `auto` recovering the simulated q."""
    rng = np.random.default_rng(2024)
    n_core, n = 1500, 40
    t = np.cumsum(rng.uniform(0.5, 1.5, n))
    t -= t[0]
    q = 1e-4
    r = rng.uniform(0.02, 0.04, (n_core, n)) ** 2
    truth, z, moving = simulate(rng, n_core, t, q, r)
    z[rng.random(z.shape) < 0.1] = np.nan
    q_hat, note = km.fit_process_noise(km.Inputs(z, r), t, km._kalman_params("velocity", "continuous", 0.0))
    assert not note and 0.6 * q < q_hat < 1.6 * q, q_hat
    out = engine_smoother(z, r, t, "velocity", q, "continuous", threads=2)
    d, s = out["mean"][:, :, 0], out["sd"][:, :, 0]
    started = np.isfinite(d)
    raw_rmse = np.sqrt(np.nanmean((z - truth) ** 2))
    rmse = np.sqrt(np.mean((d - truth)[started] ** 2))
    assert rmse < 0.6 * raw_rmse, (rmse, raw_rmse)
    # Coverage at one random epoch per core point (among the started ones).
    picks = np.array([rng.choice(np.flatnonzero(started[c])) for c in range(n_core)])
    rows = np.arange(n_core)
    covered = np.abs(d[rows, picks] - truth[rows, picks]) <= Z95 * s[rows, picks]
    rate, half = covered.mean(), 3.29 * math.sqrt(0.95 * 0.05 / n_core)  # 99.9 % binomial interval
    assert 0.95 - half <= rate <= 0.95 + half, rate
    flagged = (np.abs(d) > Z95 * s)[~moving][started[~moving]]
    assert flagged.mean() <= 0.05, flagged.mean()
    # The Kalman band is narrower than the single epoch's LOD: more change detected as significant.
    assert np.nanmedian(s) < 0.6 * np.median(np.sqrt(r))


def test_the_same_bits_for_any_thread_count():
    rng = np.random.default_rng(9)
    z = rng.normal(0, 1, (700, 25))
    r = np.full_like(z, 0.5)
    t = np.arange(25.0)
    a = engine_smoother(z, r, t, "acceleration", 1e-3, "continuous", threads=1)
    b = engine_smoother(z, r, t, "acceleration", 1e-3, "continuous", threads=2)
    assert a["mean"].tobytes() == b["mean"].tobytes() and a["sd"].tobytes() == b["sd"].tobytes()


def test_bad_input_is_a_clear_error():
    from m3c2kit.base.errors import M3C2Error
    z, r = np.zeros((1, 3)), np.ones((1, 3))
    with pytest.raises(M3C2Error, match="must not decrease"):
        engine_smoother(z, r, [0.0, 2.0, 1.0], "velocity", 1.0, "continuous")
    with pytest.raises(M3C2Error, match="process noise"):
        engine_smoother(z, r, [0.0, 1.0, 2.0], "velocity", -1.0, "continuous")
    with pytest.raises(Exception, match="process-noise"):
        km._check(km.KalmanOptions(process_noise=-1.0))


#: SHA-256 of the independent model's outputs below (mean, sd, log-likelihood, moments, rounded to
#: 1e-12) as the engine gave them before issue 41 added the shared model (main's build, 7746409):
#: `--observation independent` must stay the references' filter, number for number.
INDEPENDENT_BEFORE_ISSUE_41 = "458f6d3813ade8b0a7a8069ca419ea426bd3c45a575ac38afc16ca21e8f177cc"


def test_the_independent_model_gives_the_numbers_it_gave_before_the_shared_one():
    import hashlib
    rng = np.random.default_rng(41)
    rows, n = 50, 30
    t = np.cumsum(rng.uniform(0.2, 2, n))
    z = rng.normal(0, 0.05, (rows, n)) + 0.01 * t
    z[rng.random(z.shape) < 0.1] = np.nan
    v = rng.uniform(1e-4, 4e-3, (rows, n))
    h = hashlib.sha256()
    for order in (2, 3):
        for discrete in (False, True):
            for prior in (None, t[0] - 1):
                p = engine.kalman_params(order=order, discrete_noise=discrete, process_noise=1e-3, prior_time=prior,
                                         observation="independent")
                moments = np.full((rows, n, order + order * (order + 1) // 2), np.nan)
                r = engine.kalman_smooth(z, v, t, moments, p, threads=1)
                for a in (r["mean"], r["sd"], r["log_likelihood"], moments):
                    h.update(np.round(a, 12).tobytes())
    assert h.hexdigest() == INDEPENDENT_BEFORE_ISSUE_41
