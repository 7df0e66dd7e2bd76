"""Makes analysis.zip, the py4dgeo SpatiotemporalAnalysis archive test_series.py imports (see
PROVENANCE.md). Run with py4dgeo installed: python make_archive.py"""
import datetime as dt
from pathlib import Path

import numpy as np
import py4dgeo

HERE = Path(__file__).resolve().parent


def surface(seed, n, dz):
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, 6, (n, 2))
    z = 0.2 * np.sin(xy[:, 0]) + 0.01 * rng.normal(size=n) + dz * (xy[:, 0] > 3)
    return np.column_stack([xy, z])


def main():
    out = HERE / "analysis.zip"
    out.unlink(missing_ok=True)
    analysis = py4dgeo.SpatiotemporalAnalysis(str(out), force=True)
    t0 = dt.datetime(2024, 1, 1, 12)
    reference = py4dgeo.Epoch(surface(0, 3000, 0.0), timestamp=t0)
    analysis.reference_epoch = reference
    analysis.corepoints = reference.cloud[::60]
    analysis.m3c2 = py4dgeo.M3C2(cyl_radius=0.3, normal_radii=(0.5,), max_distance=1.0)
    epochs = [py4dgeo.Epoch(surface(k + 1, 2500, 0.02 * k), timestamp=t0 + dt.timedelta(hours=k + 1)) for k in range(6)]
    analysis.add_epochs(*epochs)
    print(out, out.stat().st_size, "bytes", analysis.distances.shape)


if __name__ == "__main__":
    main()
