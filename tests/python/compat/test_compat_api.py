"""Issue 43: more of py4dgeo 1.2.0's API in m3c2kit.compat.py4dgeo, with py4dgeo's semantics (its
source read in the validation environment): exceptions py4dgeo's users catch, timestamps, the
directions() hook and any orientation vector, CloudCompareM3C2, write_m3c2_results_to_las,
regular_corepoint_grid, Epoch.transform, the log file, and a clear error for what is absent."""
from __future__ import annotations

import datetime
import logging
from pathlib import Path

import numpy as np
import pytest

import m3c2kit
import m3c2kit.compat.py4dgeo as p4
from m3c2kit.base.errors import CloudReadError, UsageError

REPO = Path(__file__).resolve().parents[3]
TUTORIAL = REPO / "tests" / "data" / "py4dgeo-tutorial"


@pytest.fixture(scope="module")
def pair():
    e1, e2 = p4.read_from_xyz(TUTORIAL / "plane_horizontal_t1.xyz", TUTORIAL / "plane_horizontal_t2.xyz")
    return e1, e2, e1.cloud[::7]


def tilted(seed=3, n=3000, shift=0.05):
    """A rough plane z = 0.3 x (normal along (-0.29, 0, 0.96)) and a copy raised by `shift`."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, 10, (n, 2))
    z = 0.3 * xy[:, 0] + rng.normal(0, 0.01, n)
    ref = np.column_stack([xy, z])
    cmp_ = ref + [0, 0, shift] + rng.normal(0, 0.01, (n, 3))
    return p4.Epoch(ref), p4.Epoch(cmp_), ref[::60]


@pytest.mark.parametrize("builtin", [p4.Py4DGeoError, ValueError, UsageError])
def test_a_bad_argument_is_every_exception_a_py4dgeo_user_catches(pair, builtin):
    e1, e2, core = pair
    with pytest.raises(builtin, match="cyl_radius"):
        p4.M3C2(epochs=(e1, e2), corepoints=core, normal_radii=[1.0]).run()


@pytest.mark.parametrize("builtin", [p4.Py4DGeoError, FileNotFoundError, CloudReadError])
def test_a_missing_file_is_file_not_found_and_py4dgeos(tmp_path, builtin):
    with pytest.raises(builtin, match="missing.xyz: no such file"):
        p4.read_from_xyz(tmp_path / "missing.xyz")


def test_errors_are_logged_as_py4dgeo_logs_them(tmp_path, pair):
    log = tmp_path / "py4dgeo.log"
    p4.set_py4dgeo_logfile(log)
    try:
        with pytest.raises(p4.Py4DGeoError):
            p4.Epoch(np.zeros((4, 2)))
        assert "cloud must be an (N, 3) array" in log.read_text()
    finally:
        logger = logging.getLogger("py4dgeo")
        for h in [h for h in logger.handlers if getattr(h, "_m3c2kit_logfile", False)]:
            logger.removeHandler(h)
            h.close()


@pytest.mark.parametrize("given, expected", [
    ("2024-05-01T12:30:00", datetime.datetime(2024, 5, 1, 12, 30)),
    ("2024-05-01", datetime.datetime(2024, 5, 1)),
    (datetime.date(2023, 2, 3), datetime.datetime(2023, 2, 3)),
    ((2024, 32), datetime.datetime(2024, 2, 1)),  # a LAS header's (year, day of year)
    (np.datetime64("2020-01-02T03:04"), datetime.datetime(2020, 1, 2, 3, 4)),
    (None, None),
])
def test_timestamps_are_normalised_as_py4dgeos(given, expected):
    e = p4.Epoch(np.zeros((3, 3)), timestamp=given)
    assert e.timestamp == expected
    assert e.metadata == {"timestamp": None if expected is None else str(expected), "scanpos_info": None}
    assert e[::2].timestamp == expected and e.copy().timestamp == expected


def test_a_timestamp_not_understood_is_py4dgeos_error():
    with pytest.raises(p4.Py4DGeoError, match="'next tuesday' was not understood: .*ISO 8601"):
        p4.Epoch(np.zeros((3, 3)), timestamp="next tuesday")


def test_read_from_las_takes_the_headers_creation_date(tmp_path):
    import laspy
    path = tmp_path / "e.las"
    m3c2kit.io.write_cloud_table(path, np.random.default_rng(0).uniform(0, 1, (10, 3)), {})
    with laspy.open(path) as f:
        created = f.header.creation_date
    assert created is not None
    e = p4.read_from_las(path)
    assert e.timestamp == datetime.datetime(created.year, created.month, created.day)


def test_any_orientation_vector_orients_the_normals():
    e1, e2, core = tilted()
    o = np.array([-1.0, 0.0, 1.0])  # oblique: refused before (issue 43)
    m = p4.M3C2(epochs=(e1, e2), corepoints=core, normal_radii=[1.0], cyl_radius=0.5, max_distance=1.0,
                orientation_vector=o)
    d, _ = m.run()
    n = m.directions()
    assert (n @ o >= 0).all() and np.allclose(np.abs(n[:, 0]), 0.3 / np.hypot(1, 0.3), atol=0.02)
    # the vertical shift seen along the normal: +shift x n_z, normals towards o (n_z > 0)
    assert np.nanmedian(d) == pytest.approx(0.05 / np.hypot(1, 0.3), abs=0.003)
    flipped, _ = p4.M3C2(epochs=(e1, e2), corepoints=core, normal_radii=[1.0], cyl_radius=0.5, max_distance=1.0,
                         orientation_vector=-o).run()
    np.testing.assert_array_equal(flipped, -d)


def test_a_subclass_directions_are_used_even_with_normal_radii():
    """Issue 43: a subclass overriding directions() was ignored when normal_radii were given
    (all 300 distances differed, up to 38 mm). py4dgeo's run() takes self.directions()."""
    e1, e2, core = tilted()

    class Vertical(p4.M3C2):
        def directions(self):
            return np.array([[0.0, 0.0, 1.0]])

    d, _ = Vertical(epochs=(e1, e2), corepoints=core, normal_radii=[1.0], cyl_radius=0.5, max_distance=1.0).run()
    r = m3c2kit.compare(e1.cloud, e2.cloud, core, normal_source="vertical", projection_scale=1.0, max_depth=1.0,
                        min_points=1, lod="z")
    np.testing.assert_array_equal(d, r.distance)
    assert np.nanmedian(d) == pytest.approx(0.05, abs=0.005)  # vertical: the whole shift

    class Wrong(p4.M3C2):
        def directions(self):
            return np.zeros((2, 3))

    with pytest.raises(p4.Py4DGeoError, match=r"Wrong.directions\(\) must return \(1, 3\) or \(50, 3\)"):
        Wrong(epochs=(e1, e2), corepoints=core, cyl_radius=0.5).run()


def test_a_subclass_callback_is_refused_not_ignored():
    e1, e2, core = tilted()

    class Custom(p4.M3C2):
        def callback_distance_calculation(self):
            return lambda *a: 0.0

    with pytest.raises(p4.UnsupportedArgument, match="Custom.callback_distance_calculation overrides py4dgeo's "
                                                     "C\\+\\+ callback, which m3c2kit's engine never calls"):
        Custom(epochs=(e1, e2), corepoints=core, normal_radii=[1.0], cyl_radius=0.5).run()


def test_normals_from_any_cloud_and_directions_before_run():
    e1, e2, core = tilted()
    third = p4.Epoch(e1.cloud[::2])
    m = p4.M3C2(epochs=(e1, e2), corepoints=core, normal_radii=[1.0], cyl_radius=0.5, max_distance=1.0,
                cloud_for_normals=third)
    with pytest.raises(ValueError, match="radii are only available after directions"):
        m.directions_radii()
    n = m.directions()  # computed before any run, kept for it (py4dgeo's)
    fitted = m3c2kit.normals(third.cloud, core, normal_scale=2.0)
    np.testing.assert_array_equal(n, fitted["normal"])
    np.testing.assert_array_equal(m.directions_radii(), 1.0)
    d, _ = m.run()
    r = m3c2kit.compare(e1.cloud, e2.cloud, core, normal_source="core", core_normals=n, projection_scale=1.0,
                        max_depth=1.0, min_points=1, lod="z")
    np.testing.assert_array_equal(d, r.distance)


def test_cloudcompare_m3c2_takes_diameters(pair):
    e1, e2, core = pair
    cc, cc_unc = p4.CloudCompareM3C2(epochs=(e1, e2), corepoints=core, NormalScale=[3.0], SearchScale=2.0,
                                     SearchDepth=3.0, RegistrationError=0.01, UseMedian=False).run()
    ours, unc = p4.M3C2(epochs=(e1, e2), corepoints=core, normal_radii=[1.5], cyl_radius=1.0, max_distance=3.0,
                        registration_error=0.01).run()
    np.testing.assert_array_equal(cc, ours)
    for field in unc.dtype.names:
        np.testing.assert_array_equal(cc_unc[field], unc[field])


def test_write_m3c2_results_to_las(pair, tmp_path):
    e1, e2, core = pair
    m = p4.M3C2(epochs=(e1, e2), corepoints=core, normal_radii=[1.5], cyl_radius=1.0, max_distance=3.0)
    d, u = m.run()
    out = tmp_path / "r.las"
    p4.write_m3c2_results_to_las(out, m, {"distances": d, "lod": u["lodetection"]})
    back = m3c2kit.read(out)
    np.testing.assert_allclose(back.xyz, core, rtol=0, atol=5e-5)
    np.testing.assert_allclose(back.fields["distances"], d, rtol=1e-6, atol=5e-5)
    np.testing.assert_allclose(back.fields["lod"], u["lodetection"], rtol=1e-6, atol=5e-5)
    with pytest.raises(p4.Py4DGeoError, match="r.xyz is no .las or .laz path"):
        p4.write_m3c2_results_to_las(tmp_path / "r.xyz", m, {})
    with pytest.raises(ValueError, match="attribute 'short' must hold one value per core point"):
        p4.write_m3c2_results_to_las(tmp_path / "s.las", m, {"short": d[:3]})
    assert not (tmp_path / "s.las").exists()


def test_regular_corepoint_grid():
    square = p4.regular_corepoint_grid((0, 0), (1, 2), (3, 3), zval=5.0)
    expected = [[x, y, 5.0] for x in np.linspace(0, 1, 3) for y in np.linspace(0, 2, 3)]  # py4dgeo's, square
    np.testing.assert_array_equal(square, expected)
    wide = p4.regular_corepoint_grid((0, 0), (1, 1), (2, 5))  # py4dgeo 1.2.0 leaves rows unset here
    assert wide.shape == (10, 3) and len(np.unique(wide, axis=0)) == 10
    with pytest.raises(ValueError, match="num_points must be >= 1"):
        p4.regular_corepoint_grid((0, 0), (1, 1), (0, 5))


def test_epoch_transform_as_py4dgeos():
    rng = np.random.default_rng(1)
    cloud = rng.uniform(0, 10, (20, 3))
    normals = np.tile([0.0, 0.0, 1.0], (20, 1))
    e = p4.Epoch(cloud, normals=normals)
    angle = np.radians(10)
    rot = np.array([[np.cos(angle), -np.sin(angle), 0], [np.sin(angle), np.cos(angle), 0], [0, 0, 1]])
    rp = np.array([5.0, 5.0, 0.0])
    e.transform(rotation=rot, translation=[1.0, 2.0, 3.0], reduction_point=rp)
    np.testing.assert_allclose(e.cloud, (cloud - rp) @ rot.T + [1, 2, 3] + rp, rtol=0, atol=1e-12)
    np.testing.assert_allclose(e.normals, normals @ rot.T, atol=1e-15)
    assert len(e.transformation) == 1
    with pytest.raises(ValueError, match="3x4 or 4x4"):
        e.transform(affine_transformation=np.eye(3))


@pytest.mark.parametrize("name", ["C2C", "SearchTree", "Vapc", "MemoryPolicy"])
def test_a_py4dgeo_name_not_provided_says_what_to_use(name):
    with pytest.raises(AttributeError, match=f"does not provide py4dgeo's {name}; use instead"):
        getattr(p4, name)


def test_calculate_normals_as_py4dgeos():
    e1, _, _ = tilted(n=1500)
    n = e1.calculate_normals(radius=1.0, orientation_vector=np.array([1.0, 0.0, 0.0]))
    assert n is e1.normals and n.shape == e1.cloud.shape
    ok = np.isfinite(n).all(axis=1)
    assert ok.mean() > 0.99 and (n[ok] @ [1.0, 0.0, 0.0] >= 0).all()  # towards +x: the plane rises along x
    np.testing.assert_allclose(np.abs(n[ok]), np.abs(m3c2kit.normals(e1.cloud, normal_scale=2.0)["normal"][ok]),
                               atol=0)
    with pytest.raises(ValueError, match="radius must be a positive number"):
        e1.calculate_normals(radius=0)


def test_py4dgeos_own_suite_bugs_are_fixed(tmp_path):
    """validation/py4dgeo_test_suite.py found these against py4dgeo 1.2.0's own tests: the cloud and the
    search trees cannot be assigned (Py4DGeoError), the log file is created by its first record, and a
    single epoch is refused at construction."""
    e = p4.Epoch(np.zeros((3, 3)))
    with pytest.raises(p4.Py4DGeoError, match="cannot be changed"):
        e.cloud = 42
    with pytest.raises(p4.Py4DGeoError, match="KDTree"):
        e.kdtree = None
    log = tmp_path / "log.txt"
    p4.set_py4dgeo_logfile(str(log))
    assert not log.exists()
    with pytest.raises(p4.Py4DGeoError, match="Exactly two epochs"):
        p4.M3C2(epochs=(e,), corepoints=np.zeros((1, 3)), cyl_radius=1.0)
    assert log.exists()  # the error was logged, as py4dgeo's
    with pytest.raises(AttributeError, match="enable_trace; use instead"):
        p4.enable_trace
