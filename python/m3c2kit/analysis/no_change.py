"""No-change simulations of the level of detection (section 3.3, Appendix B; docs/validation.md,
"Calibration of the LOD"): two clouds sampling the same surface, so every "significant change" is
a false positive, and a calibrated LOD at confidence c flags 1 - c of the core points.

Each core point gets its own cylinder (d = 1, core points 3 apart, imposed vertical normals as in
the paper's 5.2.2) holding exactly n points of each cloud, drawn uniformly in a disc of diameter
0.9 d. Heights: Gaussian or Laplace noise of standard deviation 1 on a flat surface, or a
self-affine rough surface (Hurst exponent 0.7, sum of random-phase waves with amplitude ~
wavelength^H from 0.02 d to 30 d) plus Gaussian noise of 0.1: within a cylinder the heights are
then a fixed but non-Gaussian (often skewed or bimodal) distribution sampled twice.
"""
from __future__ import annotations

import math

import numpy as np

from . import lod_engine

NOISES = ("gaussian", "laplace", "self-affine")
D = 1.0
SPACING = 3.0
DISC_RADIUS = 0.45
HURST = 0.7


def _grid(cores: int) -> np.ndarray:
    side = math.ceil(math.sqrt(cores))
    i = np.arange(cores)
    return np.column_stack([SPACING * (i % side), SPACING * (i // side), np.zeros(cores)])


class _SelfAffine:
    """z(x, y) = sum_k a_k cos(k . x + phi_k), |k| log-spaced, a_k ~ lambda_k^H: a self-affine
    surface over the wavelengths [0.02, 30] (sigma(L) ~ L^H between them, section 5.2.2, eq. 3)."""

    def __init__(self, rng: np.random.Generator, waves: int = 48):
        lam = np.geomspace(0.02, 30.0, waves)
        theta = rng.uniform(0, 2 * np.pi, waves)
        self.k = (2 * np.pi / lam)[:, None] * np.column_stack([np.cos(theta), np.sin(theta)])
        self.phase = rng.uniform(0, 2 * np.pi, waves)
        # Equal log-spaced bands: amplitude^2 per band ~ lambda^(2H), normalised to sigma 1 at L = 1.
        amp = lam ** HURST
        self.amp = amp / math.sqrt(0.5 * np.sum(amp[lam <= 1.0] ** 2))

    def __call__(self, xy: np.ndarray) -> np.ndarray:
        out = np.zeros(len(xy))
        for k, a, ph in zip(self.k, self.amp, self.phase):
            out += a * np.cos(xy @ k + ph)
        return out


def _cloud(core: np.ndarray, n: int, noise: str, surface, rng: np.random.Generator) -> np.ndarray:
    m = len(core)
    r = DISC_RADIUS * np.sqrt(rng.uniform(size=(m, n)))
    a = rng.uniform(0, 2 * np.pi, size=(m, n))
    xy = (core[:, None, :2] + np.stack([r * np.cos(a), r * np.sin(a)], axis=-1)).reshape(-1, 2)
    if noise == "gaussian":
        z = rng.standard_normal(m * n)
    elif noise == "laplace":
        z = rng.laplace(scale=1 / math.sqrt(2), size=m * n)
    else:
        z = surface(xy) + 0.1 * rng.standard_normal(m * n)
    return np.column_stack([xy, z])


def scene(noise: str, n: int, cores: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(reference, compared, core points, max_depth) of one no-change simulation."""
    if noise not in NOISES:
        raise ValueError(f"noise must be one of {NOISES}, got {noise!r}")
    rng = np.random.default_rng([seed, n, NOISES.index(noise)])
    core = _grid(cores)
    surface = _SelfAffine(rng) if noise == "self-affine" else None
    ref = _cloud(core, n, noise, surface, rng)
    cmp = _cloud(core, n, noise, surface, rng)
    depth = 2.0 * float(max(np.abs(ref[:, 2]).max(), np.abs(cmp[:, 2]).max())) + 1.0
    return ref, cmp, core, depth


def false_positive_rates(noise: str, n: int, cores: int, seed: int, *, statistics=lod_engine.STATISTICS,
                         lods=lod_engine.LODS, confidences=(0.95, 0.99), bootstrap_samples: int = 200,
                         threads: int = 0) -> dict:
    """{(statistic, lod, confidence): (false positives, core points with a LOD)} on one scene."""
    ref, cmp, core, depth = scene(noise, n, cores, seed)
    out = {}
    for statistic in statistics:
        for lod in lods:
            for conf in confidences:
                p = lod_engine.vertical_params(D, depth, statistic=statistic, lod=lod, confidence=conf,
                                               bootstrap_samples=bootstrap_samples, seed=seed)
                r = lod_engine.run(ref, cmp, core, p, threads=threads)
                ok = r["status"] == 0
                if not np.all(r["n1"] == n) or not np.all(r["n2"] == n):
                    raise AssertionError("a cylinder does not hold exactly n points of each cloud")
                out[(statistic, lod, conf)] = (int(np.sum(r["significant"][ok])), int(ok.sum()))
    return out


def binomial_interval(p: float, trials: int, level: float = 0.99) -> tuple[float, float]:
    """Central interval [lo, hi] / trials holding at least `level` of Binomial(trials, p): lo the
    smallest k with P(X <= k) > (1 - level) / 2, hi the largest with P(X >= k) > (1 - level) / 2
    (exact, from log-probabilities)."""
    tail = (1 - level) / 2
    log_p, log_q = math.log(p), math.log1p(-p)
    pmf = [math.exp(math.lgamma(trials + 1) - math.lgamma(k + 1) - math.lgamma(trials - k + 1) + k * log_p
                    + (trials - k) * log_q) for k in range(trials + 1)]
    acc, lo = 0.0, 0
    while acc + pmf[lo] <= tail:
        acc += pmf[lo]
        lo += 1
    acc, hi = 0.0, trials
    while acc + pmf[hi] <= tail:
        acc += pmf[hi]
        hi -= 1
    return lo / trials, hi / trials
