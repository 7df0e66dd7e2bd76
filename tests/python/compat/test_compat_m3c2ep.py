"""py4dgeo's M3C2EP in m3c2kit.compat.py4dgeo (compat/py4dgeo/m3c2ep.py): a seeded two-scanner scene
with a known change, measured through the compatibility class and through m3c2kit.compare with
the same inputs; the rock glacier's real transformation, covariance and reduction point
(../shared/data/pairs/ahk-corepoints-m3c2ep, skipped without it) applied to a compared epoch
measured in its own frame; py4dgeo's errors; and, where py4dgeo 1.2.0 is installed, the same
script run by both (py4dgeo_both.py)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import m3c2kit
import m3c2kit.compat.py4dgeo as p4
from m3c2kit.base.errors import UsageError
from m3c2kit.io.cloud import Cloud
from py4dgeo_both import ours, theirs

CHANGE = 0.02  # the compared surface is this much higher where x > 5 (compared - reference > 0)
SIGMA_RANGE, SIGMA_ANGLE = 0.004, 3e-4
SCANNERS = np.array([[-12.0, 5.0, 3.0], [22.0, 1.0, 4.0]])
AHK = "pairs/ahk-corepoints-m3c2ep"
AHK_PLACE = np.array([652900.0, 5189100.0, 2500.0])  # the subarea of its core points' file name


def height(x, y):
    return 0.05 * np.sin(0.5 * x) * np.cos(0.4 * y) + 0.002 * np.sin(9.1 * x + 3.7 * y)


def scan(rng, change: float, scanners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A 10 x 10 m surface seen from each scanner (3000 points each) with polar noise; ids from 1."""
    clouds, ids = [], []
    for k, origin in enumerate(scanners):
        xy = rng.uniform(0, 10, (3000, 2))
        surface = np.column_stack([xy, height(*xy.T) + np.where(xy[:, 0] > 5, change, 0.0)])
        d = surface + (scanners[0] - SCANNERS[0]) - origin  # the scene moves with the scanners
        r = np.linalg.norm(d, axis=1) + rng.normal(0, SIGMA_RANGE, len(d))
        yaw = np.arctan2(d[:, 1], d[:, 0]) + rng.normal(0, SIGMA_ANGLE, len(d))
        zen = np.arccos(d[:, 2] / np.linalg.norm(d, axis=1)) + rng.normal(0, SIGMA_ANGLE, len(d))
        clouds.append(origin + np.column_stack([r * np.sin(zen) * np.cos(yaw), r * np.sin(zen) * np.sin(yaw),
                                                r * np.cos(zen)]))
        ids.append(np.full(len(d), k + 1, np.int32))
    return np.concatenate(clouds), np.concatenate(ids)


def alignment_covariance() -> np.ndarray:
    """Cxx (12x12) of a small rotation (0.4 mrad) and shift (1 mm) as the 12 parameters r11..r33, t."""
    basis = np.zeros((12, 6))
    basis[1, 2], basis[2, 1], basis[3, 2], basis[5, 0], basis[6, 1], basis[7, 0] = -1, 1, 1, -1, -1, 1
    basis[9:, 3:] = np.eye(3)
    return basis @ np.diag([4e-4**2] * 3 + [1e-3**2] * 3) @ basis.T


def scanpos_info(origins: np.ndarray) -> dict:
    """py4dgeo's scan positions. sigma_range_ppm is m3c2kit's (py4dgeo reads no such key): at
    1e3 sqrt(sigma_range) m3c2kit's range error sqrt(a^2 + (b 1e-6 r)^2) is py4dgeo's
    sqrt(a^2 + a 1e-6 r^2); the two angular sigmas are equal, so py4dgeo's swap of them changes
    nothing: the two models coincide (docs/validation.md §7.3)."""
    return {str(k + 1): {"origin": [float(c) for c in o], "sigma_range": SIGMA_RANGE,
                         "sigma_range_ppm": 1e3 * np.sqrt(SIGMA_RANGE), "sigma_scan": SIGMA_ANGLE,
                         "sigma_yaw": SIGMA_ANGLE} for k, o in enumerate(origins)}


def core_points(rng, n: int = 150, place=np.zeros(3)) -> np.ndarray:
    xy = rng.uniform(0.5, 9.5, (n, 2))
    xy = xy[np.abs(xy[:, 0] - 5) > 0.5]  # off the step, where a cylinder would straddle it
    return np.column_stack([xy, height(*xy.T)]) + place


@pytest.fixture(scope="module")
def scene():
    rng = np.random.default_rng(5)
    reference, ids1 = scan(rng, 0.0, SCANNERS)
    compared, ids2 = scan(rng, CHANGE, SCANNERS)
    core = np.vstack([core_points(rng), [[30.0, 30.0, 0.0]]])  # the last one far from every point
    return dict(reference=reference, ids1=ids1, compared=compared, ids2=ids2, core=core, cxx=alignment_covariance(),
                scanners=SCANNERS)


def epochs(s: dict, compared=None, origins2=None) -> tuple[p4.Epoch, p4.Epoch]:
    e1 = p4.Epoch(s["reference"], scanpos_info=scanpos_info(s["scanners"]))
    e1.scanpos_id = s["ids1"]
    e2 = p4.Epoch(s["compared"] if compared is None else compared,
                  scanpos_info=scanpos_info(s["scanners"] if origins2 is None else origins2))
    e2.scanpos_id = s["ids2"]
    return e1, e2


def run(s: dict, **kwargs):
    e1, e2 = epochs(s, kwargs.pop("compared", None), kwargs.pop("origins2", None))
    m = p4.M3C2EP(epochs=(e1, e2), corepoints=s["core"], corepoint_normals=np.array([[0.0, 0.0, 1.0]]),
                  cyl_radius=0.25, max_distance=0.3, **{"Cxx": s["cxx"], **kwargs})
    return m, *m.run()


def small_motion(angle: float = 3e-4) -> np.ndarray:
    """tfM: a rotation about z by `angle` and a shift of a few millimetres."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0, 0.003], [s, c, 0.0, -0.002], [0.0, 0.0, 1.0, 0.001]])


def regions(core: np.ndarray, place=np.zeros(3)) -> tuple[np.ndarray, np.ndarray]:
    x = core[:, 0] - place[0]
    return x < 5, (x > 5) & (x < 10)


def test_a_known_change_is_measured_compared_minus_reference(scene):
    m, distances, uncertainties, covariance = run(scene)
    assert uncertainties.dtype == p4.UNCERTAINTY_DTYPE and covariance.dtype == p4.COVARIANCE_DTYPE
    assert m.name == "M3C2EP" and covariance["cov1"].shape == (len(scene["core"]), 3, 3)
    still, raised = regions(scene["core"])
    assert abs(np.nanmedian(distances[still])) < 0.002
    assert abs(np.nanmedian(distances[raised]) - CHANGE) < 0.002
    computed = np.isfinite(distances)
    assert computed[:-1].mean() > 0.9 and not computed[-1]  # the far core point: no cylinder
    assert np.isfinite(uncertainties["lodetection"][computed]).all()
    # spread is the propagated standard deviation of each centre along the normal (0, 0, 1).
    np.testing.assert_allclose(uncertainties["spread1"][computed], np.sqrt(covariance["cov1"][computed, 2, 2]),
                               rtol=1e-12)
    assert (uncertainties["num_samples1"][computed] >= 5).all()
    # Below 5 points a cylinder gives no distance, as py4dgeo's; the full result keeps ours.
    few = (uncertainties["num_samples1"] < 5) | (uncertainties["num_samples2"] < 5)
    assert np.isnan(distances[few]).all() and (~computed == few).all()
    assert np.isnan(uncertainties["spread2"][few]).all() and np.isnan(covariance["cov2"][few]).all()
    assert np.isfinite(m.result.distance[few][:-1]).all()
    assert m.result.status_counts().get("ok", 0) == computed.sum()


def test_the_numbers_are_m3c2kit_compares_with_py4dgeos_model(scene, tmp_path):
    # A transformation about a reduction point, given to both: the compat class maps tfM, Cxx,
    # refPointMov and the epochs' scan positions onto m3c2kit's EP inputs.
    tfm, red = small_motion(), np.array([5.0, 5.0, 0.0])
    _, distances, uncertainties, _ = run(scene, tfM=tfm, refPointMov=red)
    table = np.array([[k + 1, *o, SIGMA_RANGE, 1e3 * np.sqrt(SIGMA_RANGE), SIGMA_ANGLE, SIGMA_ANGLE]
                      for k, o in enumerate(scene["scanners"])])
    r = m3c2kit.compare(Cloud(scene["reference"], fields={"scan": scene["ids1"]}),
                        Cloud(scene["compared"], fields={"scan": scene["ids2"]}), scene["core"],
                        projection_scale=0.5, max_depth=0.3, normal_source="core",
                        core_normals=np.tile([0.0, 0.0, 1.0], (len(scene["core"]), 1)), uncertainty="ep",
                        scan_positions=table, scan_position_field="scan", transform=tfm,
                        alignment_covariance=scene["cxx"], reduction_point=red, ep_weights="matrix",
                        ep_covariance="mean-of-points", ep_lod="published", min_points=5)
    computed = np.isfinite(distances)
    np.testing.assert_array_equal(distances[computed], r.distance[computed])
    np.testing.assert_array_equal(uncertainties["lodetection"], r.lod)
    np.testing.assert_array_equal(uncertainties["spread2"][computed], r.spread2[computed])


def test_perform_trans_false_takes_the_compared_epoch_as_already_transformed(scene):
    tfm, red = small_motion(), np.array([5.0, 5.0, 0.0])
    moved = (scene["compared"] - red) @ tfm[:, :3].T + tfm[:, 3] + red
    _, a, ua, ca = run(scene, tfM=tfm, refPointMov=red)
    _, b, ub, cb = run(scene, tfM=tfm, refPointMov=red, compared=moved, perform_trans=False)
    np.testing.assert_allclose(b, a, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ub["lodetection"], ua["lodetection"], rtol=1e-7)
    np.testing.assert_allclose(cb["cov2"], ca["cov2"], rtol=1e-6, atol=1e-15)


def test_the_rock_glaciers_transformation_moves_the_compared_epoch_onto_the_reference(shared_data):
    """AHK's tfM (a 12 cm shift and a 1.5e-4 rotation and scale), Cxx and reduction point, as py4dgeo's
    M3C2-EP example gives them, with a compared epoch measured in its own frame (the true surface
    moved by the inverse of tfM): the distances are the known change only if tfM is applied to the
    compared epoch about refPointMov, as py4dgeo does."""
    folder = shared_data / AHK
    tfm = np.loadtxt(folder / "tfM.csv", delimiter=",")
    cxx = np.loadtxt(folder / "Cxx.csv", delimiter=",")
    red = np.loadtxt(folder / "redPoint.csv", delimiter=",")
    rng = np.random.default_rng(8)
    scanners = SCANNERS + AHK_PLACE
    reference, ids1 = scan(rng, 0.0, scanners)
    true_compared, ids2 = scan(rng, CHANGE, scanners)
    inverse = np.linalg.inv(tfm[:, :3])
    measured = (true_compared - red - tfm[:, 3]) @ inverse.T + red
    origins = (scanners - red - tfm[:, 3]) @ inverse.T + red
    s = dict(reference=reference, ids1=ids1, compared=measured, ids2=ids2, cxx=cxx, scanners=scanners,
             core=core_points(rng, 120, AHK_PLACE))
    _, distances, uncertainties, _ = run(s, tfM=tfm, refPointMov=red, origins2=origins)
    still, raised = regions(s["core"], AHK_PLACE)
    assert abs(np.nanmedian(distances[still])) < 0.002
    assert abs(np.nanmedian(distances[raised]) - CHANGE) < 0.002
    # Cxx's alignment error is shared by every point: the LoD holds it whatever the point count.
    assert np.nanmin(uncertainties["lodetection"]) > 0.01
    # The files themselves, as `m3c2 compare` reads them, give the same numbers.
    r = m3c2kit.compare(Cloud(reference, fields={"scan": ids1}), Cloud(measured, fields={"scan": ids2}),
                        s["core"], projection_scale=0.5, max_depth=0.3, normal_source="core",
                        core_normals=np.tile([0.0, 0.0, 1.0], (len(s["core"]), 1)), uncertainty="ep",
                        scan_positions=np.array([[k + 1, *o, SIGMA_RANGE, 1e3 * np.sqrt(SIGMA_RANGE), SIGMA_ANGLE,
                                                  SIGMA_ANGLE] for k, o in enumerate(scanners)]),
                        scan_position_field="scan", transform=str(folder / "tfM.csv"),
                        alignment_covariance=str(folder / "Cxx.csv"), reduction_point=str(folder / "redPoint.csv"),
                        ep_weights="matrix", ep_covariance="mean-of-points", ep_lod="published", min_points=5)
    # (one scan-position table for both epochs there: the compared origins differ by the
    # transformation's few centimetres, which moves the propagated errors, not the distances)
    computed = np.isfinite(distances)
    np.testing.assert_allclose(distances[computed], r.distance[computed], rtol=0, atol=2e-4)


def test_scan_positions_as_py4dgeos_epoch_holds_them(scene):
    e = p4.Epoch(scene["reference"][:10], scanpos_info={"2": {"origin": [1, 2, 3]}, "1": {"origin": [0, 0, 0]}})
    assert e.scanpos_info == [{"origin": [0, 0, 0]}, {"origin": [1, 2, 3]}]  # py4dgeo's list, by id
    assert e.metadata["scanpos_info"] == e.scanpos_info
    e.additional_dimensions = np.zeros(10, dtype=[("intensity", "<u2")])
    e.scanpos_id = np.arange(10) % 2 + 1
    assert e.scanpos_id.dtype == np.int32 and e.additional_dimensions.dtype.names == ("intensity", "scanpos_id")
    assert (e[::2].scanpos_id == 1).all()
    with pytest.raises(ValueError, match="keys must be the scan position ids 1..2"):
        p4.Epoch(scene["reference"][:10], scanpos_info={"0": {}, "1": {}})
    with pytest.raises(ValueError, match="one id per point"):
        e.scanpos_id = [1, 2]


def test_errors_are_py4dgeos(scene):
    e1, e2 = epochs(scene)
    common = dict(corepoints=scene["core"], corepoint_normals=np.array([[0.0, 0.0, 1.0]]), cyl_radius=0.25)

    def raises(kind, match, **kwargs):
        with pytest.raises(kind, match=match) as e:
            p4.M3C2EP(**{"epochs": (e1, e2), **common, "max_distance": 0.3, **kwargs}).run()
        assert isinstance(e.value, p4.Py4DGeoError) and isinstance(e.value, ValueError)
        assert isinstance(e.value, UsageError)

    raises(p4.UnsupportedArgument, "registration_error", registration_error=0.01)
    raises(p4.UnsupportedArgument, "robust_aggr", robust_aggr=True)
    raises(p4.UnsupportedArgument, "unsupported py4dgeo argument.*maxneigh", maxneigh=10)
    raises(ValueError, r"tfM must have shape \(3, 4\)", tfM=np.eye(4))
    raises(ValueError, r"Cxx must have shape \(12, 12\)", Cxx=np.eye(6))
    raises(ValueError, "tfM refused.*not a rotation", tfM=np.hstack([2 * np.eye(3), np.zeros((3, 1))]))
    raises(ValueError, "Cxx refused.*not symmetric", Cxx=np.triu(np.ones((12, 12))))
    raises(ValueError, "max_distance must be a positive number", max_distance=0.0)
    bare = p4.Epoch(scene["reference"])
    raises(ValueError, "reference epoch has no scanpos_info", epochs=(bare, e2))
    bare.scanpos_info = scanpos_info(SCANNERS)
    raises(ValueError, "reference epoch has no scanpos_id", epochs=(bare, e2))
    raises(ValueError, "must be an Epoch", epochs=(scene["reference"], e2))
    wrong = p4.Epoch(scene["compared"], scanpos_info=[{"origin": [0.0, 0.0, 0.0], "sigma_range": 0.01}])
    wrong.scanpos_id = scene["ids2"]
    raises(ValueError, "compared epoch's scan position 1 has no 'sigma_scan'", epochs=(e1, wrong))
    wrong.scanpos_info = [dict(scanpos_info(SCANNERS)["1"])]
    raises(ValueError, "scan position id 2, which the scan-position table does not list", epochs=(e1, wrong))


# -- the same script run by py4dgeo 1.2.0 and by the compatibility package ------------------------

M3C2EP_SCRIPT = """
import numpy as np
import py4dgeo
d = np.load(DATA)
sps = {str(k + 1): {"origin": [float(c) for c in o], "sigma_range": 0.004, "sigma_range_ppm": 1e3 * np.sqrt(0.004),
                    "sigma_scan": 3e-4, "sigma_yaw": 3e-4} for k, o in enumerate(d["scanners"])}
epoch1 = py4dgeo.Epoch(d["reference"], scanpos_info=sps)
epoch1.scanpos_id = d["ids1"]
epoch2 = py4dgeo.Epoch(d["compared"], scanpos_info=sps)
epoch2.scanpos_id = d["ids2"]
m3c2ep = py4dgeo.M3C2EP(epochs=(epoch1, epoch2), corepoints=d["core"], normal_radii=[0.5], cyl_radius=0.25,
                        max_distance=0.3, Cxx=d["cxx"], tfM=d["tfm"], refPointMov=d["red"])
distances, uncertainties, covariance = m3c2ep.run()
out = {"distance": distances, "lod": uncertainties["lodetection"], "spread1": uncertainties["spread1"],
       "spread2": uncertainties["spread2"], "n1": uncertainties["num_samples1"], "n2": uncertainties["num_samples2"],
       "cov1": covariance["cov1"], "cov2": covariance["cov2"], "normals": m3c2ep.directions()}
"""


def script_data(folder: Path, s: dict, tfm=np.eye(3, 4), red=np.zeros(3)) -> Path:
    path = folder / "m3c2ep.npz"
    np.savez(path, **{k: s[k] for k in ("reference", "ids1", "compared", "ids2", "core", "cxx", "scanners")},
             tfm=tfm, red=red)
    return path


@pytest.mark.slow
def test_m3c2ep_script_agrees_with_py4dgeo_where_the_models_coincide(scene, tmp_path):
    data = script_data(tmp_path, scene)
    mine, py4dgeos = ours(M3C2EP_SCRIPT, data), theirs(M3C2EP_SCRIPT, data)
    np.testing.assert_array_equal(np.isfinite(mine["distance"]), np.isfinite(py4dgeos["distance"]))
    both = np.isfinite(mine["distance"])
    assert both.sum() > 100
    np.testing.assert_allclose(mine["normals"][both], py4dgeos["normals"][both], rtol=0, atol=1e-9)
    # py4dgeo's M3C2EP gives reference - compared, its M3C2 and m3c2kit compared - reference.
    np.testing.assert_allclose(mine["distance"][both], -py4dgeos["distance"][both], rtol=0, atol=1e-12)
    for key in ("lod", "spread1", "spread2", "cov1", "cov2"):
        np.testing.assert_allclose(mine[key][both], py4dgeos[key][both], rtol=1e-9, atol=0, err_msg=key)
        assert np.isnan(mine[key][~both]).all() and np.isnan(py4dgeos[key][~both]).all()
    np.testing.assert_array_equal(mine["n1"][both], py4dgeos["n1"][both])
    np.testing.assert_array_equal(mine["n2"][both], py4dgeos["n2"][both])


@pytest.mark.slow
def test_m3c2ep_script_with_the_rock_glaciers_transformation_agrees_with_py4dgeo(scene, tmp_path, shared_data):
    """With AHK's real tfM, py4dgeo propagates the errors at the transformed points (defect 4 of
    docs/algorithm.md §6.5), here at the measured ones: the distances differ by a fraction of a
    millimetre, far below the level of detection (0.05 mm against 2 cm on this scene)."""
    folder = shared_data / AHK
    tfm = np.loadtxt(folder / "tfM.csv", delimiter=",")
    red = np.loadtxt(folder / "redPoint.csv", delimiter=",")
    moved = dict(scene, reference=scene["reference"] + AHK_PLACE, compared=scene["compared"] + AHK_PLACE,
                 core=scene["core"] + AHK_PLACE, scanners=scene["scanners"] + AHK_PLACE,
                 cxx=np.loadtxt(folder / "Cxx.csv", delimiter=","))
    data = script_data(tmp_path, moved, tfm, red)
    mine, py4dgeos = ours(M3C2EP_SCRIPT, data), theirs(M3C2EP_SCRIPT, data)
    both = np.isfinite(mine["distance"]) & np.isfinite(py4dgeos["distance"])
    assert both.sum() > 100
    apart = np.abs(mine["distance"][both] + py4dgeos["distance"][both])  # signs opposite, as above
    assert apart.max() < 2e-4 and apart.max() < 0.01 * np.min(mine["lod"][both])  # 0.05 mm, LoD 2 cm
    np.testing.assert_allclose(mine["lod"][both], py4dgeos["lod"][both], rtol=2e-3)
