"""Calibration of the Kalman filter's observation models (docs/series.md, "Kalman filter",
Calibration): seeded per-epoch M3C2 draws with a known truth, filtered with `--observation
shared` (the default, with its step test) and `independent` (kalman4d's and the tum-rsa fork's
model), q by maximum likelihood (the engine's `auto`).

Each cell (core point) is a rough surface of scatter sigma ~ U(1, 4) cm. The reference cylinder
holds n1 points: its mean errs by b, the mean of n1 draws, and b is in every epoch's distance;
epoch k holds n2_k points, its mean errs by e_k. So distance_k = truth_k + e_k - b, and sigma1,
sigma2 are the draws' sample standard deviations: the structure M3C2 gives (the same cylinder of
the reference against every epoch). A LOD (the independent model's variance sigma1^2/n1 +
sigma2^2/n2) needs n1, n2 >= 4 (--min-points' default). Truths: 40 % unchanged, then steps and
ramps (or, in one scene, steps) of 0.5 and 4 times the single distance's noise (below and above
it). 30 epochs a day apart
(jittered); the reference one day before the first epoch, or the first epoch itself (the
permanent laser scanning case: the reference file is epoch 0, whose distance is 0), or of unknown
time.

Measured on the (cell, epoch) pairs with an estimate, the reference epoch left out (its change is
0 by construction): coverage of the truth by the 95 % band d +- z sigma; the share of unchanged
pairs flagged (|d| > z sigma); RMSE against the truth over the raw distances' RMSE; pairs
estimated over the pairs with a raw distance.

    .venv/bin/python validation/kalman_calibration.py

Prints a markdown table. tests/python/series/test_kalman_shared.py asserts these scenes' rates."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from m3c2kit import engine as facade
from m3c2kit.base.quantiles import z_critical

MIN_POINTS = 4  # the compare default: below it no LOD
Z95 = z_critical(0.95)


@dataclass(frozen=True)
class Scene:
    name: str
    n1: tuple[int, int]  # the reference cylinder's points, uniform in [lo, hi]
    n2: tuple[int, int]  # each epoch's
    reference: str  # "before" (a day before the first epoch), "epoch" (epoch 0 is the reference file), "unknown"
    change: str = "ramp"  # the changed cells' truth: "ramp" (steady motion) or "step" (a sudden one)
    cells: int = 2000
    epochs: int = 30


SCENES = (
    Scene("reference as dense as the epochs (it is epoch 0)", (6, 15), (6, 15), "epoch"),
    Scene("reference as dense as the epochs, a day before", (6, 15), (6, 15), "before"),
    Scene("reference 20x denser", (150, 250), (6, 15), "before"),
    Scene("sparse epochs (1-3 points)", (6, 15), (1, 3), "before"),
    Scene("as dense, the reference's time unknown", (6, 15), (6, 15), "unknown"),
    Scene("as dense, steps instead of ramps", (6, 15), (6, 15), "before", "step"),
)


def _draws(rng, sigma, n):
    """Mean and sample standard deviation (NaN for n = 1) of n[i] draws N(0, sigma[i]^2)."""
    most = int(n.max())
    x = rng.normal(0.0, 1.0, (*n.shape, most)) * sigma[..., None]
    used = np.arange(most) < n[..., None]
    mean = np.where(used, x, 0.0).sum(-1) / n
    ss = np.where(used, (x - mean[..., None]) ** 2, 0.0).sum(-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        sd = np.where(n >= 2, np.sqrt(ss / (n - 1)), np.nan)
    return mean, sd


def simulate(scene: Scene, seed: int) -> dict:
    """One scene's store-like arrays (cells x epochs): distance, sigma1, n1, sigma2, n2, the
    independent model's variance, the truth, the times and the reference (time, epoch)."""
    rng = np.random.default_rng(seed)
    c, n = scene.cells, scene.epochs
    days = np.cumsum(rng.uniform(0.7, 1.3, n))
    days -= days[0]
    sigma = rng.uniform(0.01, 0.04, c)
    n1 = rng.integers(scene.n1[0], scene.n1[1] + 1, c).astype(float)
    n2 = rng.integers(scene.n2[0], scene.n2[1] + 1, (c, n)).astype(float)
    b, s1 = _draws(rng, sigma, n1)
    e, s2 = _draws(rng, np.repeat(sigma[:, None], n, 1), n2)
    noise = sigma * np.sqrt(1.0 / n1 + 1.0 / np.median(n2, axis=1))  # a single distance's sd
    kind = np.where(rng.random(c) < 0.4, "none", scene.change)
    size = np.where(rng.random(c) < 0.5, 0.5, 4.0) * noise * rng.choice([-1.0, 1.0], c)
    t_ref = 0.0 if scene.reference == "epoch" else -1.0  # the change is 0 there, by definition
    truth = np.zeros((c, n))
    at = rng.uniform(days[3], days[-4], c)
    truth[kind == "step"] = (size[:, None] * (days[None, :] >= at[:, None]))[kind == "step"]
    truth[kind == "ramp"] = (size[:, None] * (days[None, :] - t_ref) / (days[-1] - t_ref))[kind == "ramp"]
    ref_epoch, ref_time = None, None
    if scene.reference == "epoch":  # epoch 0 is the reference file: the reference against itself
        e[:, 0], s2[:, 0], n2[:, 0] = b, s1, n1
        ref_epoch = 0
    elif scene.reference == "before":
        ref_time = t_ref
    z = truth + e - b[:, None]
    n1c, s1c = np.repeat(n1[:, None], n, 1), np.repeat(s1[:, None], n, 1)
    with np.errstate(invalid="ignore"):
        lod_ok = (n1c >= MIN_POINTS) & (n2 >= MIN_POINTS)
        var = np.where(lod_ok, s1c ** 2 / n1c + s2 ** 2 / n2, np.nan)
    c_ = np.ascontiguousarray
    return {"distance": c_(z), "variance": c_(var), "spread": (c_(s1c), c_(n1c), c_(s2), c_(n2)), "truth": truth,
            "days": days, "reference": (ref_time, ref_epoch), "unchanged": kind == "none"}


def run(sim: dict, observation: str, model: str = "velocity") -> dict:
    """The smoothed distance and sd (cells x epochs) of `observation`, q by maximum likelihood."""
    order = {"velocity": 2, "acceleration": 3}[model]
    shared = observation == "shared"

    def params(q):
        return facade.kalman_params(order=order, discrete_noise=False, process_noise=q, observation=observation,
                                    reference=sim["reference"] if shared else None)

    var = None if shared else sim["variance"]
    spread = sim["spread"] if shared else None
    if not shared and not np.isfinite(var).any():  # no LOD anywhere (sparse epochs): nothing observed
        nan = np.full(sim["distance"].shape, np.nan)
        return {"d": nan, "sd": nan, "q": np.nan}
    q, _ = facade.kalman_fit_process_noise(sim["distance"], var, sim["days"], params(0.0), spread=spread)
    size = order + shared
    moments = np.full((*sim["distance"].shape, size + size * (size + 1) // 2), np.nan)
    r = facade.kalman_smooth(sim["distance"], var, sim["days"], moments, params(q), spread=spread)
    return {"d": r["mean"][:, :, 0], "sd": r["sd"][:, :, 0], "q": q}


def metrics(sim: dict, out: dict) -> dict:
    """Coverage, flagged unchanged, RMSE / raw RMSE and pairs estimated / raw (module docstring)."""
    keep = np.ones(sim["truth"].shape, bool)
    if sim["reference"][1] is not None:
        keep[:, sim["reference"][1]] = False
    d, sd, truth, z = out["d"], out["sd"], sim["truth"], sim["distance"]
    est = np.isfinite(d) & keep
    raw = np.isfinite(z) & keep
    flagged = np.abs(d) > Z95 * sd
    unchanged = est & sim["unchanged"][:, None]
    rmse = lambda err: float(np.sqrt(np.mean(err ** 2)))  # noqa: E731
    return {"coverage": float(np.mean(np.abs(d - truth)[est] <= Z95 * sd[est])) if est.any() else np.nan,
            "flagged": float(flagged[unchanged].mean()) if unchanged.any() else np.nan,
            "error": rmse((d - truth)[est]) / rmse((z - truth)[raw]) if est.any() else np.nan,
            "estimated": float(est.sum() / raw.sum())}


def main() -> int:
    print("| scene | observation | 95 % band covers the truth | unchanged flagged | RMSE / raw | estimated / raw |")
    print("|---|---|---|---|---|---|")
    for i, scene in enumerate(SCENES):
        sim = simulate(scene, 100 + i)
        for observation in ("shared", "independent"):
            m = metrics(sim, run(sim, observation))
            pct = lambda v: "no estimate" if np.isnan(v) else f"{100 * v:.1f} %"  # noqa: E731
            error = "no estimate" if np.isnan(m["error"]) else f"{m['error']:.2f}"
            print(f"| {scene.name} | {observation} | {pct(m['coverage'])} | {pct(m['flagged'])} | {error} | "
                  f"{m['estimated']:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
