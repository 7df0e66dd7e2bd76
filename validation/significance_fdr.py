"""p-values and false-discovery control on seeded simulated surveys (docs/validation.md,
"p-values and false-discovery control"; issue 34).

    cd /tmp && /work/main/.venv/bin/python /work/main/validation/significance_fdr.py [--runs 20] [--threads 2]

A flat survey of SIDE x SIDE core points 1 m apart, each with its own square metre of points
(DENSITY per m^2, about 20 per cylinder of d = 0.5: the cylinders do not overlap), independent
Gaussian noise of NOISE in both epochs, vertical normals, the command line's default LOD
(`auto`: Welch's t below 30 points). Scenarios: no change; a change of CHANGE on a share of the
core points. Per scenario and run: the Kolmogorov-Smirnov test of the unchanged core points'
p-values against the uniform law, and the false-discovery proportion (false / flagged) and the
power (flagged / changed) of the plain 95 % test, of --fdr Q with BH and with BY. Writes the
table (docs/validation/significance_fdr.md) and the figure (docs/validation/significance_fdr.png).
"""
from __future__ import annotations

import argparse
import pathlib
import time

import numpy as np
from scipy import stats

import m3c2kit

SIDE, DENSITY, NOISE, CHANGE = 50, 100, 0.01, 0.012
SHARES = (0.0, 0.05, 0.2, 0.5)
Q = 0.05
SEED = 34_000
OUT = pathlib.Path(__file__).resolve().parents[1] / "docs" / "validation"
COMMON = dict(normal_source="vertical", projection_scale=0.5, max_depth=0.5)


def survey(seed: int, share: float):
    rng = np.random.default_rng(seed)
    gx, gy = np.meshgrid(np.arange(SIDE) + 0.5, np.arange(SIDE) + 0.5)
    core = np.column_stack([gx.ravel(), gy.ravel(), np.zeros(SIDE * SIDE)])
    changed = rng.random(len(core)) < share
    clouds = []
    for k in range(2):
        n = DENSITY * SIDE * SIDE
        xy = rng.uniform(0, SIDE, (n, 2))
        z = rng.normal(0.0, NOISE, n)
        if k == 1:
            cell = np.floor(xy[:, 1]).astype(int) * SIDE + np.floor(xy[:, 0]).astype(int)
            z = z + CHANGE * changed[cell]
        clouds.append(np.column_stack([xy, z]))
    return clouds[0], clouds[1], core, changed


def one_run(seed: int, share: float, threads: int) -> dict:
    ref, cmp_, core, changed = survey(seed, share)
    out = {}
    for method in ("bh", "by"):
        r = m3c2kit.compare(ref, cmp_, core, **COMMON, fdr=Q, fdr_method=method, threads=threads, warn=False)
        out[method] = r.significant_fdr.astype(bool)
    out["plain"] = r.significant.astype(bool)
    null_p = r.p_value[~changed & np.isfinite(r.p_value)]
    row = {"ks": stats.kstest(null_p, "uniform").pvalue if len(null_p) else np.nan,
           "null_flagged": float(np.mean(null_p < 0.05))}
    for name, flags in out.items():
        row[f"fdp_{name}"] = (flags & ~changed).sum() / max(int(flags.sum()), 1)
        row[f"power_{name}"] = (flags & changed).sum() / changed.sum() if changed.any() else np.nan
    return row


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    rows = []
    for share in SHARES:
        t0 = time.time()
        runs = [one_run(SEED + 1000 * int(100 * share) + i, share, args.threads) for i in range(args.runs)]
        mean = {k: float(np.nanmean([r[k] for r in runs])) if share or not k.startswith("power") else np.nan
                for k in runs[0]}
        # Under no change the KS p-values of the runs are themselves uniform: report their share < 0.05.
        mean["ks_rejected"] = float(np.mean([r["ks"] < 0.05 for r in runs]))
        rows.append((share, mean))
        print(f"# share {share}: {args.runs} runs, {time.time() - t0:.0f} s", flush=True)
    lines = [f"{args.runs} seeded runs per row, {SIDE * SIDE} core points each, Q = {Q}, change {CHANGE} m on the "
             f"changed share, noise {NOISE} m per point, about 20 points per cylinder, `--lod auto`.", "",
             "| changed share | unchanged flagged at 95 % | KS rejects uniform p (5 %) | mean FDP plain 95 % | "
             "mean FDP BH | mean FDP BY | power plain | power BH | power BY |",
             "|---|---|---|---|---|---|---|---|---|"]
    for share, m in rows:
        def f(v):
            return "n/a" if np.isnan(v) else f"{v:.3f}"
        lines.append(f"| {share:g} | {f(m['null_flagged'])} | {f(m['ks_rejected'])} | {f(m['fdp_plain'])} | "
                     f"{f(m['fdp_bh'])} | {f(m['fdp_by'])} | {f(m['power_plain'])} | {f(m['power_bh'])} | "
                     f"{f(m['power_by'])} |")
    text = "\n".join(lines) + "\n"
    print(text)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "significance_fdr.md").write_text(text)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
    shares = [s for s, _ in rows]
    for name, style in (("plain", "o-"), ("bh", "s-"), ("by", "^-")):
        label = {"plain": "plain 95 %", "bh": f"BH, Q = {Q}", "by": f"BY, Q = {Q}"}[name]
        a.plot(shares, [m[f"fdp_{name}"] for _, m in rows], style, label=label)
        b.plot(shares[1:], [m[f"power_{name}"] for _, m in rows[1:]], style, label=label)
    a.axhline(Q, color="grey", ls="--", lw=1)
    a.set(xlabel="share of changed core points", ylabel="mean false-discovery proportion", title="FDP")
    b.set(xlabel="share of changed core points", ylabel="power (flagged / changed)", title="power")
    a.legend()
    fig.tight_layout()
    fig.savefig(OUT / "significance_fdr.png", dpi=110)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
