"""docs/series/kalman.png: one core point's raw M3C2 distances with their LOD, the Kalman filter's
estimate (forward pass) and the RTS smoother's, each with its 95 % band, and the truth, from a
seeded simulation (docs/series.md, "Kalman filter").

    .venv/bin/python validation/kalman_figure.py [docs/series/kalman.png]"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from m3c2kit import engine
from m3c2kit.series import kalman as km

Z95 = 1.959963984540054


def simulation(seed: int = 4):
    """Irregular epochs over 60 days (a 10-day gap), a slope creeping then a 4 cm slump on days
    25-32, observed with sd 6-12 mm and some epochs missing."""
    rng = np.random.default_rng(seed)
    days = np.sort(np.concatenate([rng.uniform(0, 38, 45), rng.uniform(48, 60, 15)]))
    truth = 0.0004 * days - 0.04 / (1 + np.exp(-(days - 28.5) / 1.2))
    sd = rng.uniform(0.006, 0.012, len(days))
    z = truth + rng.normal(0, sd)
    z[rng.random(len(days)) < 0.08] = np.nan
    return days, truth, z, sd


def main(out: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    days, truth, z, sd = simulation()
    p = km._kalman_params("velocity", "continuous", 0.0)  # each epoch's sd independent: the figure's model
    q, _ = km.fit_process_noise(km.Inputs(z[None, :].copy(), (sd ** 2)[None, :].copy()), days, p)
    p = km._kalman_params("velocity", "continuous", q)
    moments = np.full((1, len(days), 5), np.nan)
    r = engine.kalman_smooth(z[None, :].copy(), (sd ** 2)[None, :].copy(), days, moments, p, threads=1)
    filt, filt_sd = moments[0, :, 0], np.sqrt(moments[0, :, 2])
    smooth, smooth_sd = r["mean"][0, :, 0], r["sd"][0, :, 0]
    fig, ax = plt.subplots(figsize=(9, 4.2), dpi=110)
    ax.plot(days, truth * 100, color="k", lw=1, ls=":", label="truth")
    ax.errorbar(days, z * 100, yerr=Z95 * sd * 100, fmt="o", ms=3, color="tab:red", ecolor="tab:red", alpha=0.6,
                elinewidth=0.8, label="M3C2 distance ± LOD (95 %)")
    ax.plot(days, filt * 100, color="tab:blue", lw=1, label="Kalman filter (forward)")
    ax.fill_between(days, (filt - Z95 * filt_sd) * 100, (filt + Z95 * filt_sd) * 100, color="tab:blue", alpha=0.12)
    ax.plot(days, smooth * 100, color="tab:green", lw=1.8, label="RTS smoother ± 95 % band")
    ax.fill_between(days, (smooth - Z95 * smooth_sd) * 100, (smooth + Z95 * smooth_sd) * 100, color="tab:green",
                    alpha=0.3)
    ax.set_xlabel("days")
    ax.set_ylabel("change (cm)")
    ax.set_title(f"one core point, velocity model, q = {q:.2g} m²/day³ (maximum likelihood)", fontsize=10)
    ax.legend(fontsize=8, loc="lower left")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, metadata={"Software": None})
    print(f"wrote {out} (q = {q:.4g})")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[1] / "docs/series/kalman.png")
