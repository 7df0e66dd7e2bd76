"""py4dgeo's time-series API in m3c2kit.compat.py4dgeo (compat/py4dgeo/segmentation.py and the
files it imports): py4dgeo's 4D-OBC user workflow (SpatiotemporalAnalysis, add_epochs,
RegionGrowingAlgorithm) with only the import changed, on a seeded synthetic series whose one
change event (a deposit on a disc, ramping up over four epochs and kept) is known: the object
found covers it; the analysis reopened from its folder; temporal_averaging against a direct
median; the committed py4dgeo archive (tests/data/py4dgeo_series) read through m3c2kit's importer;
py4dgeo's errors; and, where py4dgeo 1.2.0 is installed, the same script run by both
(py4dgeo_both.py): the same distances, seeds and objects (our 4D-OBC in its py4dgeo mode), and
py4dgeo's own archive of it read back."""
from __future__ import annotations

import datetime
import io
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

import m3c2kit.compat.py4dgeo as p4
from m3c2kit.compat.py4dgeo import segmentation
from m3c2kit.series import store as series_store
from py4dgeo_both import ours, theirs

EPOCHS, POINTS, SIDE = 30, 6000, 12.0  # 30 hourly epochs of a 12 m x 12 m tilted plane, 3 mm of noise
CENTRE, RADIUS, HEIGHT = np.array([4.0, 6.0]), 2.0, 0.08
FIRST, LAST = 10, 13  # the deposit rises over epochs (distance columns) 10..13 and stays
START = datetime.datetime(2024, 5, 1)
ARCHIVE = Path(__file__).resolve().parents[2] / "data" / "py4dgeo_series" / "analysis.zip"  # py4dgeo 1.2.0's

SCRIPT = """\
import datetime
import numpy as np
import py4dgeo
data = np.load(DATA)
clouds = [data[f"arr_{k}"] for k in range(len(data.files) - 1)]
start = datetime.datetime(2024, 5, 1)
analysis = py4dgeo.SpatiotemporalAnalysis(DATA.replace(".npz", "_analysis.zip"), force=True)
analysis.reference_epoch = py4dgeo.Epoch(clouds[0], timestamp=start)
analysis.corepoints = data["core"]
analysis.m3c2 = py4dgeo.M3C2(cyl_radius=0.3, normal_radii=[0.5], max_distance=1.0)
epochs = [py4dgeo.Epoch(c, timestamp=start + datetime.timedelta(hours=k + 1)) for k, c in enumerate(clouds[1:])]
analysis.add_epochs(*epochs)
algo = py4dgeo.RegionGrowingAlgorithm(neighborhood_radius=0.75, window_width=8, window_min_size=3, minperiod=4,
                                      window_penalty=0.1, height_threshold=0.03, min_segments=10)
objects = algo.run(analysis)
members = [np.sort(o.indices) for o in objects]
out = {"distances": analysis.distances, "lod": analysis.uncertainties["lodetection"],
       "hours": np.array([td.total_seconds() / 3600 for td in analysis.timedeltas]),
       "seeds": np.array([(s.index, s.start_epoch, s.end_epoch) for s in analysis.seeds]).reshape(-1, 3),
       "objects": np.array([(o.seed.index, o.start_epoch, o.end_epoch) for o in objects]).reshape(-1, 3),
       "thresholds": np.array([o.threshold for o in objects]),
       "sizes": np.array([len(m) for m in members]),
       "members": np.concatenate(members + [np.zeros(0, int)]),
       "dtw": np.array([o.distance(i) for o, m in zip(objects, members) for i in m])}
"""


def change(t: np.ndarray) -> np.ndarray:
    return HEIGHT * np.clip((t - FIRST + 1) / (LAST - FIRST + 1), 0.0, 1.0)


def scene(seed: int = 7) -> tuple[list[np.ndarray], np.ndarray]:
    """(clouds: the reference, then one per epoch; core points on a 0.5 m grid)."""
    rng = np.random.default_rng(seed)
    clouds = []
    for t in range(EPOCHS + 1):
        xy = rng.uniform(0.0, SIDE, (POINTS, 2))
        z = 0.02 * xy[:, 0] + 0.003 * rng.standard_normal(POINTS)
        if t > 0:
            z[((xy - CENTRE) ** 2).sum(axis=1) <= RADIUS ** 2] += change(np.array(t - 1.0))
        clouds.append(np.column_stack([xy, z]))
    grid = np.mgrid[1:11.01:0.5, 1:11.01:0.5].reshape(2, -1).T
    return clouds, np.column_stack([grid, 0.02 * grid[:, 0]])


def footprint(core: np.ndarray) -> np.ndarray:
    return ((core[:, :2] - CENTRE) ** 2).sum(axis=1) <= RADIUS ** 2


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    clouds, core = scene()
    path = tmp_path_factory.mktemp("segmentation") / "scene.npz"
    np.savez(path, *clouds, core=core)
    return path


@pytest.fixture(scope="module")
def ran(data):
    """The script's numbers, run here with only its import changed."""
    return ours(SCRIPT, data)


def analysis_copy(data, tmp_path) -> p4.SpatiotemporalAnalysis:
    """The script's analysis, copied (a test may change it) and reopened by its file name."""
    shutil.copytree(data.with_name("scene_analysis.m3c2"), tmp_path / "copy.m3c2")
    return p4.SpatiotemporalAnalysis(tmp_path / "copy.zip")


def test_the_object_found_covers_the_deposit(data, ran):
    _, core = scene()
    truth = np.zeros((len(core), EPOCHS), bool)
    truth[np.ix_(footprint(core), np.arange(FIRST - 1, EPOCHS))] = True
    assert list(ran["hours"]) == list(range(1, EPOCHS + 1))
    inside = ran["distances"][footprint(core)]
    assert abs(np.median(inside[:, LAST:]) - HEIGHT) < 0.005 and abs(np.median(inside[:, :FIRST])) < 0.005
    assert len(ran["seeds"]) > 0 and len(ran["objects"]) == 1
    (seed, start, end), members = ran["objects"][0], ran["members"]
    assert footprint(core)[seed] and FIRST - 1 <= start <= LAST and end >= EPOCHS - 3  # kept to (nearly) the end
    found = np.zeros_like(truth)
    found[np.ix_(members, np.arange(start, end + 1))] = True
    iou = (found & truth).sum() / (found | truth).sum()
    assert iou > 0.6, iou
    near = np.linalg.norm(core[members, :2] - CENTRE, axis=1) <= RADIUS + 0.75  # the radius of the neighbourhood
    assert near.all() and footprint(core)[members].mean() > 0.9


def test_the_analysis_reopens_from_its_folder(data, ran, tmp_path):
    analysis = analysis_copy(data, tmp_path)
    np.testing.assert_array_equal(analysis.distances, ran["distances"])
    assert [(s.index, s.start_epoch, s.end_epoch) for s in analysis.seeds] == [tuple(s) for s in ran["seeds"]]
    (obj,) = analysis.objects
    assert obj.indices == list(ran["members"]) and obj.threshold == ran["thresholds"][0]
    assert [obj.distance(i) for i in obj.indices] == list(ran["dtw"])
    assert analysis.uncertainties.dtype == p4.UNCERTAINTY_DTYPE and analysis.uncertainties.shape == (441, EPOCHS)
    assert analysis.reference_epoch.timestamp == START and len(analysis.corepoints.cloud) == 441
    assert series_store.open_group(analysis.store)["object"].shape == (441, EPOCHS)  # the store's labels
    plt = pytest.importorskip("matplotlib.pyplot")
    obj.plot(tmp_path / "object.png")
    plt.close("all")
    assert (tmp_path / "object.png").stat().st_size > 0


def test_temporal_averaging_is_the_centred_median():
    rng = np.random.default_rng(3)
    d = rng.standard_normal((7, 40))
    d[rng.random(d.shape) < 0.1] = np.nan
    for window in (1, 4, 5, 24):
        h = window // 2
        direct = np.array([[np.nanmedian(row[max(0, t - h):t + h + 1]) if np.isfinite(row[max(0, t - h):t + h + 1])
                            .any() else np.nan for t in range(d.shape[1])] for row in d])
        smoothed = p4.temporal_averaging(d, smoothing_window=window)
        np.testing.assert_array_equal(smoothed, direct)
        assert smoothed.smoothing_window == window
    with pytest.raises(p4.Py4DGeoError, match="smoothing_window"):
        p4.temporal_averaging(d, smoothing_window=0)


def test_smoothed_distances_are_the_stores(data, tmp_path):
    analysis = analysis_copy(data, tmp_path)
    smoothed = p4.temporal_averaging(analysis.distances, smoothing_window=4)
    analysis.smoothed_distances = smoothed
    np.testing.assert_array_equal(analysis.smoothed_distances, smoothed)
    assert series_store.open_group(analysis.store)["smoothed_distance"].attrs["window"] == 4
    with pytest.raises(p4.UnsupportedArgument, match="smoothed_distances"):
        analysis.smoothed_distances = np.asarray(smoothed) + 0.0  # an array the store did not compute
    with pytest.raises(p4.UnsupportedArgument, match="not temporal_averaging"):
        analysis.smoothed_distances = smoothed * 2.0
    algo = p4.RegionGrowingAlgorithm(neighborhood_radius=0.75, window_width=8, window_min_size=3, minperiod=4,
                                     window_penalty=0.1, height_threshold=0.03, min_segments=10)
    with pytest.raises(p4.Py4DGeoError, match="objects of other parameters"):
        algo.run(analysis)  # the objects kept were found on the raw distances: py4dgeo would return them
    (obj,) = algo.run(analysis, force=True)
    assert footprint(analysis.corepoints.cloud)[obj.indices].mean() > 0.9
    assert [o.indices for o in algo.run(analysis)] == [obj.indices]  # the same parameters: reused
    analysis.invalidate_results(smoothed_distances=True)
    assert analysis.smoothed_distances is None and analysis.seeds is None and analysis.objects is None


def test_epochs_added_in_two_calls_equal_one(data, ran, tmp_path):
    """The store is created by the first add_epochs and extended by the next (m3c2 series add)."""
    clouds, core = scene()
    analysis = p4.SpatiotemporalAnalysis(tmp_path / "two.zip")
    analysis.reference_epoch = p4.Epoch(clouds[0], timestamp=START)
    analysis.corepoints = core
    analysis.m3c2 = p4.M3C2(cyl_radius=0.3, normal_radii=[0.5], max_distance=1.0)
    epochs = [p4.Epoch(c, timestamp=START + datetime.timedelta(hours=k + 1)) for k, c in enumerate(clouds[1:6])]
    analysis.add_epochs(*epochs[2:0:-1])  # sorted by time, as py4dgeo sorts them
    analysis.add_epochs(*epochs[3:])
    np.testing.assert_array_equal(analysis.distances, ran["distances"][:, 1:5])
    single = p4.M3C2(epochs=(p4.Epoch(clouds[0]), p4.Epoch(clouds[3])), corepoints=core, cyl_radius=0.3,
                     normal_radii=[0.5], max_distance=1.0)
    np.testing.assert_array_equal(single.run()[0], analysis.distances[:, 1])  # the store's column is M3C2's
    with pytest.raises(p4.Py4DGeoError, match="older than"):
        analysis.add_epochs(epochs[0])  # py4dgeo appends it out of order; the store refuses
    with pytest.raises(p4.Py4DGeoError, match="already in the analysis"):
        analysis.add_epochs(epochs[4])
    analysis.m3c2 = p4.M3C2(cyl_radius=0.3, normal_radii=[1.0], max_distance=1.0)
    with pytest.raises(p4.Py4DGeoError, match="normals differ"):
        analysis.add_epochs(p4.Epoch(clouds[6], timestamp=START + datetime.timedelta(hours=6)))
    assert analysis.distances.shape == (len(core), 4)


def test_py4dgeos_errors(data, ran, tmp_path):
    clouds, core = scene()
    analysis = p4.SpatiotemporalAnalysis(tmp_path / "new.zip")
    with pytest.raises(p4.Py4DGeoError, match="Reference epoch for analysis not yet set"):
        analysis.reference_epoch
    with pytest.raises(p4.Py4DGeoError, match="Corepoints for analysis not yet set"):
        analysis.distances
    with pytest.raises(p4.Py4DGeoError, match="need to define a timestamp"):
        analysis.reference_epoch = p4.Epoch(clouds[0])
    analysis.reference_epoch = p4.Epoch(clouds[0], timestamp=START)
    with pytest.raises(p4.Py4DGeoError, match="cannot be changed"):
        analysis.reference_epoch = p4.Epoch(clouds[0], timestamp=START)
    analysis.corepoints = core
    assert analysis.distances.shape == (len(core), 0) and analysis.timedeltas == [] and analysis.seeds is None
    with pytest.raises(p4.Py4DGeoError, match="analysis.m3c2"):
        analysis.add_epochs(p4.Epoch(clouds[1], timestamp=START))
    for name in ("distances", "uncertainties", "timedeltas"):
        with pytest.raises(p4.UnsupportedArgument, match=name):
            setattr(analysis, name, np.zeros((len(core), 1)))
    with pytest.raises(p4.UnsupportedArgument, match="seed_candidates"):
        p4.RegionGrowingAlgorithm(seed_candidates=[0, 1])
    with pytest.raises(p4.UnsupportedArgument, match="no_such_option"):
        p4.RegionGrowingAlgorithm(no_such_option=1)
    with pytest.raises(p4.Py4DGeoError, match="Subsampling factor cannot be 0"):
        p4.RegionGrowingAlgorithm(seed_subsampling=0)

    class Filtered(p4.RegionGrowingAlgorithm):
        def filter_objects(self, obj):
            return True

    with pytest.raises(p4.UnsupportedArgument, match="filter_objects"):
        Filtered().run(analysis_copy(data, tmp_path))
    with pytest.raises(p4.Py4DGeoError, match="Window width cannot be larger"):
        p4.RegionGrowingAlgorithm(window_width=EPOCHS).run(p4.SpatiotemporalAnalysis(tmp_path / "copy.zip"),
                                                           force=True)
    with pytest.raises(AttributeError, match="RegionGrowingAlgorithmBase"):
        segmentation.RegionGrowingAlgorithmBase
    (tmp_path / "mine.m3c2").mkdir()
    with pytest.raises(p4.Py4DGeoError, match="no analysis folder"):
        p4.SpatiotemporalAnalysis(tmp_path / "mine.zip", force=True)  # never deleted: not the analysis'
    assert not {"SpatiotemporalAnalysis", "RegionGrowingAlgorithm", "temporal_averaging"} & set(p4.NOT_PROVIDED)


def test_a_py4dgeo_archive_is_read_through_the_importer(tmp_path):
    shutil.copy(ARCHIVE, tmp_path / "analysis.zip")
    analysis = p4.SpatiotemporalAnalysis(tmp_path / "analysis.zip")
    with zipfile.ZipFile(ARCHIVE) as z:
        distances, uncertainties = (np.load(io.BytesIO(z.read(f"{name}.npz")))["arr_0"]
                                    for name in ("distances", "uncertainties"))
    np.testing.assert_array_equal(analysis.distances, distances)
    for field in p4.UNCERTAINTY_DTYPE.names:
        np.testing.assert_array_equal(analysis.uncertainties[field], uncertainties[field])
    assert [td.total_seconds() / 3600 for td in analysis.timedeltas] == [1, 2, 3, 4, 5, 6]
    assert analysis.smoothed_distances is None and analysis.objects is None
    with pytest.raises(p4.Py4DGeoError, match="imported from the py4dgeo archive"):
        analysis.add_epochs(p4.Epoch(np.zeros((3, 3)), timestamp=START))
    assert (tmp_path / "analysis.zip").read_bytes() == ARCHIVE.read_bytes()  # never written


def test_the_same_as_py4dgeo(data, ran, tmp_path):
    """Where the models coincide (single-scale normals, py4dgeo's 4D-OBC rule, raw series) the
    script gives py4dgeo's numbers: distances and LOD (py4dgeo's 1.96) to 1e-12 m, the same
    seeds in the same order, the same objects with the same members and thresholds."""
    got = theirs(SCRIPT, data)
    np.testing.assert_allclose(ran["distances"], got["distances"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(ran["lod"] * 1.96 / 1.959963984540054, got["lod"], rtol=0, atol=1e-12)
    for name in ("hours", "seeds", "objects", "thresholds", "sizes", "members"):
        np.testing.assert_array_equal(ran[name], got[name], err_msg=name)
    np.testing.assert_allclose(ran["dtw"], got["dtw"], rtol=0, atol=1e-12)
    # py4dgeo's own archive of the same analysis, read through m3c2kit's importer
    shutil.copy(data.with_name("scene_analysis.zip"), tmp_path / "theirs.zip")
    imported = p4.SpatiotemporalAnalysis(tmp_path / "theirs.zip")
    np.testing.assert_array_equal(imported.distances, got["distances"])
    assert [td.total_seconds() / 3600 for td in imported.timedeltas] == list(got["hours"])
    assert [o.indices for o in p4.RegionGrowingAlgorithm(
        neighborhood_radius=0.75, window_width=8, window_min_size=3, minperiod=4, window_penalty=0.1,
        height_threshold=0.03, min_segments=10).run(imported)] == [list(ran["members"])]
