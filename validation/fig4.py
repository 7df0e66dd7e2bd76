"""Reproduces Fig. 4a and 4b of Lague, Brodu & Leroux (2013), section 3.4: M3C2 vs the closest-point
baselines C2C and C2C_HF on synthetic horizontal planes.

Each cloud: 400 x 250 = 100,000 points on a grid of spacing dx (1 or 10 mm), z = Gaussian noise of
standard deviation 1 mm (numpy PCG64, reference seed 1, compared seed 2), the compared cloud raised
by a true shift of 0 to 100 mm and, for dx = 10 mm, also with a 5 mm horizontal shift along x.
M3C2: D = 50 dx, d = 10 dx, the reference's normals at every reference point (core points = the
reference), single-pass cylinder of half-length shift + 10 mm. C2C: from every compared point to
the reference. C2C_HF: least-squares plane of the 6 nearest reference points of the closest point
(CloudCompare's default kNN), both combination rules (docs/analysis.md).

    python3 validation/fig4.py [--out docs/fig4] [--quick]

Writes fig4a.png, fig4b.png, fig4_table.csv and fig4_table.md in --out and prints the table.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

try:
    import m3c2kit
except ImportError:  # run from a source checkout
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "python"))
    import m3c2kit

from m3c2kit.analysis import c2c
from m3c2kit.analysis.common import pyplot, write_csv
from m3c2kit.analysis.synthetic import noisy_plane

SHIFTS = [0, 1, 2, 3, 4, 5, 6, 8, 10, 15, 20, 30, 50, 75, 100]
NX, NY, NOISE = 400, 250, 1.0
CASES = [("a", 1.0, 0.0), ("b", 10.0, 0.0), ("b", 10.0, 5.0)]
PAPER = {"m3c2_mean_error": 0.003, "m3c2_std": 0.15, "c2c_4mm_dx1": 2.56, "c2c_4mm_dx10": 6.16, "c2c_offset_dx1": 1.95}


def run_case(dx: float, x_shift: float, shifts, threads: int) -> dict[str, list]:
    ref = noisy_plane(NX, NY, dx, NOISE, seed=1)
    normals = m3c2kit.normals(ref, ref, normal_scale=50 * dx, threads=threads)["normal"]
    rows = {k: [] for k in ("dx", "x_shift", "shift", "m3c2_mean", "m3c2_std", "m3c2_n", "c2c_mean", "c2c_std",
                            "c2c_hf_mean", "c2c_hf_std", "c2c_hf_model_mean", "c2c_hf_model_std")}
    for shift in shifts:
        cmp_ = noisy_plane(NX, NY, dx, NOISE, z=float(shift), x_shift=x_shift, seed=2)
        r = m3c2kit.compare(ref, cmp_, ref, normal_source="core", core_normals=normals, projection_scale=10 * dx,
                         max_depth=float(shift) + 10.0, threads=threads)
        dist = r.distance[np.isfinite(r.distance)]
        closer = c2c(ref, cmp_, model="plane", model_neighbours=6, rule="closer", threads=threads)
        model = c2c(ref, cmp_, model="plane", model_neighbours=6, rule="model", threads=threads)
        for k, v in (("dx", dx), ("x_shift", x_shift), ("shift", float(shift)), ("m3c2_mean", dist.mean()),
                     ("m3c2_std", dist.std(ddof=1)), ("m3c2_n", len(dist)),
                     ("c2c_mean", closer["distance"].mean()), ("c2c_std", closer["distance"].std(ddof=1)),
                     ("c2c_hf_mean", closer["hf_distance"].mean()), ("c2c_hf_std", closer["hf_distance"].std(ddof=1)),
                     ("c2c_hf_model_mean", model["hf_distance"].mean()),
                     ("c2c_hf_model_std", model["hf_distance"].std(ddof=1))):
            rows[k].append(v)
        print(f"  dx={dx:g} x_shift={x_shift:g} shift={shift:g}: M3C2 {dist.mean():.4f} +/- {dist.std(ddof=1):.3f}, "
              f"C2C {closer['distance'].mean():.3f}, C2C_HF {closer['hf_distance'].mean():.3f} / "
              f"{model['hf_distance'].mean():.3f}", flush=True)
    return rows


def summary(table: dict[str, np.ndarray]) -> list[str]:
    t = table
    a = (t["dx"] == 1) & (t["x_shift"] == 0)
    b = (t["dx"] == 10) & (t["x_shift"] == 0)
    bx = (t["dx"] == 10) & (t["x_shift"] == 5)
    m3c2_err = np.abs(t["m3c2_mean"] - t["shift"])

    def at(sel, shift, key):
        i = np.nonzero(sel & (t["shift"] == shift))[0]
        return float(t[key][i[0]]) if i.size else float("nan")
    big = a & (t["shift"] >= 4)
    lines = ["| quantity | paper | this reproduction |", "|---|---|---|",
             f"| M3C2 mean error \\|mean - true\\| (mm), all cases | 0.003 | {m3c2_err.mean():.4f} (max {m3c2_err.max():.4f}) |",
             f"| M3C2 std of distances (mm), dx = 1 mm | 0.15 | {t['m3c2_std'][a].mean():.3f} |",
             f"| M3C2 std of distances (mm), dx = 10 mm | (same as dx = 1 mm) | {t['m3c2_std'][b].mean():.3f} |",
             f"| C2C at a 4 mm shift, dx = 1 mm (mm) | 2.56 | {at(a, 4, 'c2c_mean'):.3f} |",
             f"| C2C at a 4 mm shift, dx = 10 mm (mm), without / with the 5 mm x shift | 6.16 | "
             f"{at(b, 4, 'c2c_mean'):.3f} / {at(bx, 4, 'c2c_mean'):.3f} |",
             f"| C2C offset for shifts >= 4 mm, dx = 1 mm (mean C2C - true, mm) | 1.95 (magnitude) | "
             f"{(t['c2c_mean'][big] - t['shift'][big]).mean():.3f} |",
             f"| C2C at no change, dx = 1 mm (mm) | 0.5 or 0.9 (C2C / C2C_HF, order not stated) | "
             f"{at(a, 0, 'c2c_mean'):.3f} |",
             f"| C2C_HF at no change, dx = 1 mm, rule closer / model (mm) | 0.5 or 0.9 | "
             f"{at(a, 0, 'c2c_hf_mean'):.3f} / {at(a, 0, 'c2c_hf_model_mean'):.3f} |",
             f"| dx = 1 mm, mean \\|error\\| C2C vs C2C_HF closer / model (mm) | C2C_HF less precise than C2C | "
             f"{np.abs(t['c2c_mean'][a] - t['shift'][a]).mean():.3f} vs "
             f"{np.abs(t['c2c_hf_mean'][a] - t['shift'][a]).mean():.3f} / "
             f"{np.abs(t['c2c_hf_model_mean'][a] - t['shift'][a]).mean():.3f} |",
             f"| dx = 1 mm, std C2C vs C2C_HF closer / model (mm) | | {t['c2c_std'][a].mean():.3f} vs "
             f"{t['c2c_hf_std'][a].mean():.3f} / {t['c2c_hf_model_std'][a].mean():.3f} |"]
    return lines


def table_markdown(t: dict[str, np.ndarray]) -> list[str]:
    lines = ["| dx | x shift | true | M3C2 mean | M3C2 std | C2C | C2C_HF closer | C2C_HF model |",
             "|---|---|---|---|---|---|---|---|"]
    for i in range(len(t["shift"])):
        lines.append(f"| {t['dx'][i]:g} | {t['x_shift'][i]:g} | {t['shift'][i]:g} | {t['m3c2_mean'][i]:.4f} | "
                     f"{t['m3c2_std'][i]:.3f} | {t['c2c_mean'][i]:.3f} | {t['c2c_hf_mean'][i]:.3f} | "
                     f"{t['c2c_hf_model_mean'][i]:.3f} |")
    return lines


def plots(t: dict[str, np.ndarray], out: Path) -> None:
    plt = pyplot()
    for name, cases in (("fig4a", [(1.0, 0.0)]), ("fig4b", [(10.0, 0.0), (10.0, 5.0)])):
        fig, ax = plt.subplots(figsize=(6, 5))
        for dx, xs in cases:
            sel = (t["dx"] == dx) & (t["x_shift"] == xs)
            s = t["shift"][sel]
            tag = f"dx={dx:g}" + (f", x+{xs:g}" if xs else "")
            ax.errorbar(s, t["m3c2_mean"][sel], yerr=t["m3c2_std"][sel], fmt="o-", ms=3, capsize=2, label=f"M3C2 ({tag})")
            ax.plot(s, t["c2c_mean"][sel], "s--", ms=3, label=f"C2C ({tag})")
            ax.plot(s, t["c2c_hf_mean"][sel], "^:", ms=3, label=f"C2C_HF closer ({tag})")
            ax.plot(s, t["c2c_hf_model_mean"][sel], "v:", ms=3, label=f"C2C_HF model ({tag})")
        lim = [0.5, 120]
        ax.plot(lim, lim, "k-", lw=0.6, label="1:1")
        ax.set_xscale("symlog", linthresh=1)
        ax.set_yscale("symlog", linthresh=1)
        ax.set_xlabel("true vertical displacement (mm)")
        ax.set_ylabel("measured mean displacement (mm)")
        ax.set_title(f"Fig. 4{name[-1]}: horizontal plane, noise 1 mm")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(out / f"{name}.png", dpi=120)
        plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "docs" / "fig4")
    ap.add_argument("--quick", action="store_true", help="only shifts 0, 4, 10 (a smoke test)")
    ap.add_argument("--threads", type=int, default=0)
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    shifts = [0, 4, 10] if args.quick else SHIFTS
    start = time.time()
    rows: dict[str, list] = {}
    for _, dx, xs in CASES:
        for k, v in run_case(dx, xs, shifts, args.threads).items():
            rows.setdefault(k, []).extend(v)
    t = {k: np.asarray(v, dtype=float) for k, v in rows.items()}
    write_csv(args.out / "fig4_table.csv", t)
    plots(t, args.out)
    text = ["## Summary against the paper", ""] + summary(t) + ["", "## All runs (mm)", ""] + table_markdown(t)
    (args.out / "fig4_table.md").write_text("\n".join(text) + "\n", encoding="utf-8")
    print("\n".join(text))
    print(f"\n({time.time() - start:.0f} s; files in {args.out})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
