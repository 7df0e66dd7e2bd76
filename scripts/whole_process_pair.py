"""Writes a W7-like pair as LAZ files for timing `m3c2 compare` as a whole process (issue 19).

1M + 1M points of a rough self-affine surface at 100 points/m^2 (a 100 m x 100 m square,
validation/common.py's rough_pair, seed 7), the compared epoch raised by a smooth bump, and
100k core points (the first reference points), each stored at LAS scale 0.001 m:

    python scripts/whole_process_pair.py OUTDIR
    m3c2 compare OUTDIR/reference.laz OUTDIR/compared.laz --core OUTDIR/core.laz -o out.laz \
        --normal-scale 2 --projection-scale 1 --max-depth 1 --threads 2 --verbose
"""
from __future__ import annotations

import sys
from pathlib import Path

import laspy
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "validation"))
from common import rough_pair  # noqa: E402


def write_laz(path: Path, xyz: np.ndarray) -> None:
    header = laspy.LasHeader(version="1.4", point_format=6)
    header.scales = np.array([0.001, 0.001, 0.001])
    header.offsets = np.floor(xyz.min(axis=0))
    las = laspy.LasData(header)
    las.x, las.y, las.z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    las.write(str(path))


def main(outdir: str) -> None:
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    ref, cmp, core = rough_pair(seed=7, n_points=1_000_000, n_core=100_000, size=100.0, sigma=3.0)
    for name, xyz in (("reference", ref), ("compared", cmp), ("core", core)):
        write_laz(out / f"{name}.laz", xyz)


if __name__ == "__main__":
    main(sys.argv[1])
