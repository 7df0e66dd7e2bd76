"""`m3c2 compare` end to end on real files in every input format.

A cloud compared with itself is a sharp check whatever the format: both cylinders hold the same
points in the same order, so every computed distance is exactly 0 and every LOD is finite where
both cylinders hold at least min_points points.
"""
import csv

import numpy as np
import pytest

from m3c2kit.cli.main import main

# (file under shared/data, D, d, max depth, core spacing): parameters scaled to each file's density.
CASES = {
    "las": ("readers/laspy/simple.las", 600, 400, 100, 300),
    "laz": ("readers/laspy/simple.laz", 600, 400, 100, 300),
    "copc": ("readers/laspy/simple.copc.laz", 600, 400, 100, 300),
    "e57": ("readers/e57/pye57/pumpAVisualReferenceImage.e57", 0.2, 0.1, 0.2, 0.3),
    "ascii": ("pairs/toronto-ttp/TTP_15.xyz", 10, 5, 10, 20),
}


def read_table(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def self_compare(path, out, D, d, L, spacing):
    code = main(["compare", str(path), str(path), "-o", str(out), "--core-spacing", str(spacing),
                 "--normal-scale", str(D), "--projection-scale", str(d), "--max-depth", str(L), "--quiet"])
    assert code == 0
    t = read_table(out)
    computed = np.isfinite(t["distance"])
    assert computed.sum() >= 10, f"only {computed.sum()} core points computed"
    np.testing.assert_array_equal(t["distance"][computed], 0.0)
    enough = (t["n1"] >= 4) & (t["n2"] >= 4)
    assert np.isfinite(t["lod"][enough]).all() and not t["significant"][enough].any()
    return t


@pytest.mark.slow
@pytest.mark.parametrize("fmt", sorted(CASES))
def test_self_comparison_in_every_input_format(shared_data, tmp_path, fmt):
    rel, D, d, L, spacing = CASES[fmt]
    self_compare(shared_data / rel, tmp_path / "out.csv", D, d, L, spacing)


def test_ply_input(shared_data, tmp_path):
    # The PLY files of the shared set hold at most 4 points: a real cloud is written to binary
    # PLY by `m3c2 subsample` (the reader itself is checked on every shared PLY file elsewhere).
    ply = tmp_path / "toronto.ply"
    assert main(["subsample", str(shared_data / "pairs/toronto-ttp/TTP_15.xyz"), "-o", str(ply), "--spacing", "1"]) == 0
    self_compare(ply, tmp_path / "out.csv", 10, 5, 10, 20)
    tiny = tmp_path / "tiny.csv"  # 3 points: runs, and says why nothing could be computed
    three = str(shared_data / "readers/pdal/ply/simple_binary.ply")
    assert main(["compare", three, three, "-o", str(tiny), "--normal-scale", "1", "--projection-scale", "1", "--max-depth", "1", "--quiet"]) == 0
    t = read_table(tiny)
    assert np.isnan(t["distance"]).all() and (t["status"] == 1).all()
