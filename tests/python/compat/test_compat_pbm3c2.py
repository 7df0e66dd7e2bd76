"""m3c2kit.compat.py4dgeo.PBM3C2: py4dgeo's PBM3C2 script (tests/data/py4dgeo-pbm3c2/script.py) runs
with only its import changed, pairs the segments py4dgeo pairs, and measures each facet's known move
(the truth) where py4dgeo's sign is arbitrary; golden.npz is what py4dgeo 1.2.0 computed
(validation/make_py4dgeo_pbm3c2_golden.py). Every difference is docs/pbm3c2.md's."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

import m3c2kit.compat.py4dgeo as p4
from m3c2kit.compat.py4dgeo import Py4DGeoError

pytest.importorskip("pandas")
HERE = Path(__file__).resolve().parents[2] / "data" / "py4dgeo-pbm3c2"
IMPORT = "import py4dgeo\n"


@pytest.fixture(scope="module")
def script(tmp_path_factory):
    text = (HERE / "script.py").read_text()
    assert text.count(IMPORT) == 1
    changed = text.replace(IMPORT, "import m3c2kit.compat.py4dgeo as py4dgeo\n")
    folder = tmp_path_factory.mktemp("pbm3c2")
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        namespace: dict = {"__name__": "script"}
        pytest.importorskip("sklearn")
        exec(compile(changed, "script.py", "exec"), namespace)
    finally:
        os.chdir(cwd)
    namespace["folder"] = folder
    return namespace


@pytest.fixture(scope="module")
def golden():
    z = np.load(HERE / "golden.npz")
    return {k: z[k] for k in z.files}


def _truth(script, frame):
    return script["SHIFTS"][frame["epoch0_original_id"].to_numpy(dtype=int) - 100]


@pytest.mark.parametrize("method", ["nearest", "forest"])
def test_the_pairs_are_py4dgeos_and_the_distances_the_truth(script, golden, method):
    frame = script[method]
    for column in ("epoch0_original_id", "epoch1_original_id", "epoch0_segment_id", "epoch1_segment_id"):
        np.testing.assert_array_equal(frame[column].to_numpy(dtype=float), golden[f"{method}_{column}"])
    # The truth: each facet moved by SHIFTS along its +Z-oriented normal (the scene's normals point up).
    truth = _truth(script, frame)
    np.testing.assert_allclose(frame["distance"], truth, atol=0.002)
    # py4dgeo's sign follows its eigenvector's arbitrary sign: the magnitudes agree.
    np.testing.assert_allclose(np.abs(frame["distance"]), np.abs(golden[f"{method}_distance"]), atol=2e-4)
    assert (np.sign(golden[f"{method}_distance"]) != np.sign(truth)).any(), "py4dgeo's sign is arbitrary"


def test_the_uncertainty_is_eq1_with_reg_inside_the_critical_value(script, golden):
    # py4dgeo: 1.96 sqrt(s1^2/n1 + s2^2/n2) + reg; ours 1.96 (sqrt(...) + reg) with sigma over n - 3.
    ours, theirs, reg = script["nearest"]["uncertainty"].to_numpy(), golden["nearest_uncertainty"], 0.01
    spread = (theirs - reg) / 1.959963984540054
    np.testing.assert_allclose(ours, 1.959963984540054 * (spread * np.sqrt(500 / 497) + reg), rtol=2e-3)


def test_the_metrics_are_py4dgeos(script, golden):
    metrics = script["metrics"]
    np.testing.assert_array_equal(metrics.index.to_numpy(dtype=float), golden["metrics_segment_id"])
    for column in ("cog_x", "cog_y", "cog_z", "linearity", "planarity", "sphericity"):
        np.testing.assert_allclose(metrics[column], golden[f"metrics_{column}"], atol=1e-9)
    # Unit normals, equal up to py4dgeo's arbitrary sign; ours point up (+Z).
    ours = metrics[["normal_x", "normal_y", "normal_z"]].to_numpy()
    theirs = np.column_stack([golden[f"metrics_normal_{a}"] for a in "xyz"])
    np.testing.assert_allclose(np.abs(np.sum(ours * theirs, axis=1)), 1.0, atol=1e-9)
    assert (ours[:, 2] > 0).all()
    np.testing.assert_allclose(metrics["roughness"], golden["metrics_roughness"] * np.sqrt(500 / 497), rtol=1e-9)


def test_ids_map_both_ways(script):
    alg = script["alg_nn"]
    assert alg.get_new_ids(100, 500) == (1, 41)
    assert alg.get_original_ids(1, 41) == (100, 500)


def test_py4dgeos_errors(script):
    e0, e1 = script["epoch0"], script["epoch1"]
    with pytest.raises(Py4DGeoError, match="correspondence_method"):
        p4.PBM3C2().run(e0, e1, correspondence_method="invalid")
    with pytest.raises(Py4DGeoError, match="correspondences_file is required"):
        p4.PBM3C2().run(e0, e1)
    bare = p4.Epoch(np.asarray(e0.cloud))
    with pytest.raises(Py4DGeoError, match="segment_id"):
        p4.PBM3C2().run(bare, e1, correspondence_method="nearest_neighbor")
    with pytest.raises(Py4DGeoError, match="Failed to read correspondence file"):
        p4.PBM3C2().run(e0, e1, correspondences_file=script["folder"] / "absent.csv")


def test_visualize_correspondences(script):
    pytest.importorskip("matplotlib")
    import matplotlib
    matplotlib.use("Agg")
    fig, ax = script["alg_nn"].visualize_correspondences(epoch0_segment_id=130)
    assert "130" in ax.get_title()
    with pytest.raises(ValueError, match="not found"):
        script["alg_nn"].visualize_correspondences(epoch0_segment_id=9999)
