"""m3c2kit.compat.py4dgeo: a py4dgeo script runs by changing its import and gives py4dgeo's numbers.

References, no py4dgeo needed: tests/data/py4dgeo-tutorial/golden.npz (what py4dgeo 1.2.0 itself
computed running tutorial.py, validation/make_py4dgeo_tutorial_golden.py) and the goldens of
tests/data/py4dgeo/ (test_agreement_py4dgeo.py), with py4dgeo's defects flagged there.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest

import m3c2kit
import m3c2kit.compat.py4dgeo as p4
from m3c2kit.base.errors import CloudReadError, UsageError

REPO = Path(__file__).resolve().parents[3]
TUTORIAL = REPO / "tests" / "data" / "py4dgeo-tutorial"
sys.path.insert(0, str(REPO / "validation"))
import common as C  # noqa: E402  (numpy only)

PY4DGEO_IMPORT = "import py4dgeo\n"


@pytest.fixture(scope="module")
def tutorial():
    """The tutorial script's namespace, run with only its import line changed."""
    text = (TUTORIAL / "tutorial.py").read_text()
    assert text.count(PY4DGEO_IMPORT) == 1
    changed = text.replace(PY4DGEO_IMPORT, "import m3c2kit.compat.py4dgeo as py4dgeo\n")
    # The only difference between the two scripts is that one line.
    assert [a for a, b in zip(text.splitlines(), changed.splitlines()) if a != b] == ["import py4dgeo"]
    cwd = os.getcwd()
    os.chdir(TUTORIAL)
    try:
        namespace: dict = {"__name__": "tutorial"}
        exec(compile(changed, "tutorial.py", "exec"), namespace)
    finally:
        os.chdir(cwd)
    return namespace


@pytest.fixture(scope="module")
def golden():
    z = np.load(TUTORIAL / "golden.npz")
    return {k: z[k] for k in z.files}


def test_tutorial_single_scale_distances_equal_py4dgeo(tutorial, golden):
    np.testing.assert_array_equal(tutorial["corepoints"], golden["corepoints"])
    assert np.isfinite(golden["distances"]).all()
    np.testing.assert_allclose(tutorial["distances"], golden["distances"], rtol=0, atol=1e-6)
    np.testing.assert_allclose(tutorial["robust_distances"], golden["robust_distances"], rtol=0, atol=1e-6)
    np.testing.assert_array_equal(tutorial["num_samples1"], golden["num_samples1"])
    np.testing.assert_array_equal(tutorial["num_samples2"], golden["num_samples2"])
    np.testing.assert_allclose(tutorial["spread1"], golden["spread1"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(tutorial["spread2"], golden["spread2"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(tutorial["normals"], golden["normals"], rtol=0, atol=1e-9)
    # py4dgeo's LOD uses z = 1.96, ours the exact quantile: equal once rescaled (docs/python.md).
    np.testing.assert_allclose(tutorial["lodetection"] * C.PY4DGEO_Z / C.Z95, golden["lodetection"],
                               rtol=0, atol=1e-9)


def test_uncertainties_have_py4dgeo_fields_and_types(tutorial, golden):
    unc = tutorial["uncertainties"]
    assert unc.dtype == p4.UNCERTAINTY_DTYPE
    assert unc.dtype.names == ("lodetection", "spread1", "num_samples1", "spread2", "num_samples2")
    assert len(unc) == len(golden["corepoints"])


def test_tutorial_multiscale_call_matches_here(tutorial, golden):
    # The tutorial's own call (cyl_radii, three normal radii, no max_distance). The front end lets
    # any 3-point plane be chosen, as py4dgeo does (min_points_multiscale=3); the scale rules
    # differ in general (docs/python.md) but pick the same radius on this plane, so the
    # distances agree too.
    np.testing.assert_array_equal(tutorial["ms_radii"], golden["ms_radii"])
    np.testing.assert_allclose(tutorial["ms_distances"], golden["ms_distances"], rtol=0, atol=1e-6)


def test_rough_surface_matches_py4dgeo_outside_its_defects():
    """The synthetic golden of tests/data/py4dgeo through the py4dgeo front end (radii = D/2)."""
    z = np.load(REPO / "tests" / "data" / "py4dgeo" / "rough_small.npz")
    import json
    meta = json.loads(str(z["meta"]))
    ref, cmp_, core = C.rough_pair(**meta["inputs"]["kwargs"])
    np.testing.assert_array_equal(core, z["core"])
    p = meta["params"]
    m3c2 = p4.M3C2(epochs=(p4.Epoch(ref), p4.Epoch(cmp_)), corepoints=core, normal_radii=[p["D"] / 2],
                   cyl_radius=p["d"] / 2, max_distance=p["L"])
    distances, unc = m3c2.run()
    clean = z["flags"] == C.FLAG_NONE
    assert clean.sum() > 1000
    ok = np.abs(distances - z["distance"]) <= 1e-6
    assert (ok & clean).sum() / clean.sum() >= 0.999
    np.testing.assert_array_equal(unc["num_samples1"][clean], z["n1"][clean])


def test_max_distance_below_the_radius_is_raised_to_it(golden):
    # py4dgeo's cylinder reaches at least its radius: max_distance=0 (its default) means r.
    e1, e2 = p4.read_from_xyz(TUTORIAL / "plane_horizontal_t1.xyz", TUTORIAL / "plane_horizontal_t2.xyz")
    core = e1.cloud[::7]
    a, _ = p4.M3C2(epochs=(e1, e2), corepoints=core, normal_radii=[1.5], cyl_radius=1.0).run()
    r = m3c2kit.compare(e1.cloud, e2.cloud, core, normal_scale=3.0, projection_scale=2.0, max_depth=1.0,
                        min_points=1)
    # run() takes its normals from directions(), as py4dgeo's; the engine renormalises given
    # normals, so the last bit may differ from normals it fits itself.
    np.testing.assert_allclose(a, r.distance, rtol=0, atol=1e-15)
    b, _ = p4.M3C2(epochs=(e1, e2), corepoints=core, normal_radii=[1.5], cyl_radius=1.0, max_distance=3.0).run()
    np.testing.assert_allclose(b, golden["distances"], atol=1e-6, rtol=0)


def test_unknown_and_unsupported_arguments_are_named():
    e = p4.Epoch(np.zeros((3, 3)))
    with pytest.raises(p4.UnsupportedArgument, match="unsupported py4dgeo argument.*cyl_radiuss"):
        p4.M3C2(epochs=(e, e), corepoints=e.cloud, normal_radii=[1.0], cyl_radiuss=1.0)
    with pytest.raises(UsageError, match="cyl_radius=r"):
        p4.M3C2(epochs=(e, e), corepoints=e.cloud, normal_radii=[1.0]).run()
    with pytest.raises(UsageError, match="cyl_radii must hold exactly one"):
        p4.M3C2(epochs=(e, e), corepoints=e.cloud, normal_radii=[1.0], cyl_radii=[1.0, 2.0]).run()
    with pytest.raises(UsageError, match="orientation_vector must be a finite non-zero 3-vector"):
        p4.M3C2(epochs=(e, e), corepoints=e.cloud, normal_radii=[1.0], cyl_radius=1.0,
                orientation_vector=[0.0, 0.0, 0.0]).run()
    with pytest.raises(UsageError, match="normal_radii"):
        p4.M3C2(epochs=(e, e), corepoints=e.cloud, cyl_radius=1.0).run()
    with pytest.raises(p4.UnsupportedArgument, match="scanpos"):
        p4.Epoch(np.zeros((3, 3)), scanpos={})


def test_orientation_and_normal_options_reach_the_engine():
    e1, e2 = p4.read_from_xyz(TUTORIAL / "plane_horizontal_t1.xyz", TUTORIAL / "plane_horizontal_t2.xyz")
    core = e1.cloud[::7]
    up, _ = p4.M3C2(epochs=(e1, e2), corepoints=core, normal_radii=[1.5], cyl_radius=1.0, max_distance=3).run()
    m = p4.M3C2(epochs=(e1, e2), corepoints=core, normal_radii=[1.5], cyl_radius=1.0, max_distance=3,
                orientation_vector=np.array([0, 0, -2.0]))
    down, _ = m.run()
    np.testing.assert_allclose(down, -up, atol=1e-12)
    assert np.all(m.directions()[:, 2] < 0)
    np.testing.assert_array_equal(m.directions_radii(), 1.5)
    # Imposed normals, one for all core points (py4dgeo's (1, 3) form).
    fixed, _ = p4.M3C2(epochs=(e1, e2), corepoints=core, cyl_radius=1.0, max_distance=3,
                       corepoint_normals=np.array([[0.0, 0.0, 1.0]])).run()
    r = m3c2kit.compare(e1.cloud, e2.cloud, core, normal_source="vertical", projection_scale=2.0, max_depth=3.0,
                        min_points=1)
    np.testing.assert_allclose(fixed, r.distance, atol=1e-12)
    # Normals from the compared epoch.
    other, _ = p4.M3C2(epochs=(e1, e2), corepoints=core, normal_radii=[1.5], cyl_radius=1.0, max_distance=3,
                       cloud_for_normals=e2).run()
    r = m3c2kit.compare(e1.cloud, e2.cloud, core, normal_scale=3.0, normal_source="compared",
                        projection_scale=2.0, max_depth=3.0, min_points=1)
    np.testing.assert_allclose(other, r.distance, rtol=0, atol=1e-15)  # given normals renormalised


def test_read_from_xyz_forms(tmp_path):
    one = p4.read_from_xyz(TUTORIAL / "plane_horizontal_t1.xyz")
    assert isinstance(one, p4.Epoch) and one.cloud.shape == (441, 3) and one.cloud.dtype == np.float64
    f = tmp_path / "c.csv"
    f.write_text("x,y,z,nx,ny,nz,i\n1,2,3,0,0,1,7\n4,5,6,0,1,0,8\n")
    e = p4.read_from_xyz(f, xyz_columns=[0, 1, 2], normal_columns=[3, 4, 5], additional_dimensions={6: "i"},
                         delimiter=",", skip_header=1)
    np.testing.assert_array_equal(e.cloud, [[1, 2, 3], [4, 5, 6]])
    np.testing.assert_array_equal(e.normals, [[0, 0, 1], [0, 1, 0]])
    np.testing.assert_array_equal(e.additional_dimensions["i"], [7, 8])
    with pytest.raises(CloudReadError, match="no such file"):
        p4.read_from_xyz(tmp_path / "missing.xyz")
    bad = tmp_path / "bad.xyz"
    bad.write_text("1 2 3\n1 2\n")
    with pytest.raises(CloudReadError, match="bad.xyz"):
        p4.read_from_xyz(bad)


def test_read_from_las_keeps_dimensions():
    laz = REPO / "data" / "toronto-ttp" / "TTP_15.laz"
    e = p4.read_from_las(laz, additional_dimensions={"intensity": "i"})
    cloud = m3c2kit.read(laz)
    np.testing.assert_array_equal(e.cloud, cloud.xyz)
    np.testing.assert_array_equal(e.additional_dimensions["i"], cloud.fields["intensity"])
    with pytest.raises(CloudReadError, match="no dimension 'nope'"):
        p4.read_from_las(laz, additional_dimensions={"nope": "n"})


def test_threads_setting():
    before = p4.get_num_threads()
    try:
        p4.set_num_threads(1)
        assert p4.get_num_threads() == 1
        with pytest.raises(UsageError):
            p4.set_num_threads(-1)
    finally:
        p4.set_num_threads(before)


def test_package_ships_py_typed():
    # PEP 561: type checkers read the annotations of an installed package only with this marker.
    assert (Path(m3c2kit.__file__).parent / "py.typed").is_file()
