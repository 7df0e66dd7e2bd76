"""TAM3C2's LOD on unchanged surfaces (docs/series.md, "TAM3C2", Calibration): the share of
(core point, epoch) cells flagged significant at 95 % for each LOD statistic (--lod z, the
reference's; t; auto), weighting and window ratio, on a seeded series with no change (a tilted
plane with 1 cm iid noise, a dense reference and 11 sparse epochs at irregular hours, core points
every 0.3 m, cylinder radius 0.3 m, --required-points 10). Calibrated means about 5 %.

    .venv/bin/python validation/tam3c2_calibration.py

Prints a markdown table. tests/python/series/test_tam3c2.py asserts the same scene's rates."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "python" / "series"))
from test_tam3c2 import _stable_series, settings  # noqa: E402  (the test's scene, one definition)

from m3c2kit import engine as facade  # noqa: E402


def main() -> int:
    clouds, days, core = _stable_series()
    pool = facade.tam3c2_pool(clouds, days)
    print("| LOD | weights | window ratio | distances | flagged at 95 % |")
    print("|---|---|---|---|---|")
    for statistic in ("z", "t", "auto"):
        for weights in ("none", "linear", "gaussian"):
            for ratio in (0.2, 1.0):
                s = settings(weights=weights, window_ratios=[ratio], min_points=10, cylinder_radius=0.3,
                             registration_error=0.0, confidence=0.95, lod=statistic)
                r = facade.tam3c2(pool, core, 0, range(1, len(clouds)), s)
                ok = np.isfinite(r["distance"])
                flagged = float((np.abs(r["distance"][ok]) > r["lod"][ok]).mean())
                print(f"| {statistic} | {weights} | {ratio:g} | {int(ok.sum())} | {100 * flagged:.1f} % |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
