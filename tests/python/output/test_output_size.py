"""A LAZ output is no larger than twice the input for the same points (issue 13), and its
scaled-integer columns read back within the documented bound (m3c2kit.io.quantised: lengths
and normal components at 1e-4, at most 5e-5 off) with NaN kept, through m3c2kit's reader and
through laspy (raw integers, no_data declared)."""
from __future__ import annotations

import io
from pathlib import Path

import laspy
import numpy as np
import pytest

import m3c2kit
from m3c2kit.cli.main import main
from m3c2kit.io import read_cloud
from m3c2kit.io.quantised import LENGTH_QUANTUM, UNIT_QUANTUM

REPO = Path(__file__).resolve().parents[3]
TTP = REPO / "data" / "toronto-ttp"
BOUND = 0.5 * LENGTH_QUANTUM * (1 + 1e-9)  # rounding to the quantum, plus float64 rounding
COMPACT = ("distance", "lod", "significant", "n1", "n2", "status")


def laz_size(las: laspy.LasData) -> int:
    out = io.BytesIO()
    las.write(out, do_compress=True)
    return len(out.getvalue())


def same_points_laz(path: Path, xyz: np.ndarray) -> int:
    """Bytes of the input file's points at `xyz` (every point when all are there), as LAZ."""
    las = laspy.read(path)
    pts = np.column_stack([las.x, las.y, las.z])
    if len(pts) != len(xyz) or not np.array_equal(pts, xyz):
        row = np.dtype([("x", "<f8"), ("y", "<f8"), ("z", "<f8")])
        key = np.ascontiguousarray(pts).view(row).ravel()
        order = np.argsort(key, kind="stable")
        found = order[np.searchsorted(key[order], np.ascontiguousarray(xyz).view(row).ravel())]
        assert np.array_equal(pts[found], xyz)
        las.points = las.points[found]
    return laz_size(las)


def run(tmp_path, reference, compared, *args, name="out.laz") -> Path:
    out = tmp_path / name
    assert main(["compare", str(reference), str(compared), "-o", str(out), "-q", *args]) == 0
    return out


def test_demo_output_is_at_most_twice_the_input(tmp_path):
    # scripts/demo.sh's run: core points every 5 m, multi-scale normals.
    out = run(tmp_path, TTP / "TTP_15.laz", TTP / "TTP_23.laz", "--core-spacing", "5", "--normal-scale", "8:40:8",
              "--projection-scale", "10", "--max-depth", "30")
    base = same_points_laz(TTP / "TTP_15.laz", read_cloud(out).xyz)
    assert out.stat().st_size <= 2 * base, (out.stat().st_size, base)


def test_every_point_output_is_at_most_twice_the_input_file(tmp_path):
    out = run(tmp_path, TTP / "TTP_23.laz", TTP / "TTP_15.laz", "--normal-scale", "10", "--projection-scale", "10",
              "--max-depth", "30")
    assert len(read_cloud(out)) == len(read_cloud(TTP / "TTP_23.laz"))
    assert out.stat().st_size <= 2 * (TTP / "TTP_23.laz").stat().st_size


def _survey(path: Path, seed: int, shift: float) -> None:
    """An airborne-like survey: a rough surface with the attributes a LAS file carries."""
    rng = np.random.default_rng(seed)
    n = 60000
    x, y = rng.uniform(0, 200, n), rng.uniform(0, 200, n)
    z = 2.0 * np.sin(x / 15.0) + 1.5 * np.cos(y / 20.0) + rng.normal(0, 0.03, n) + shift * (x > 100)
    header = laspy.LasHeader(version="1.4", point_format=6)
    header.scales, header.offsets = np.array([0.001] * 3), np.array([630000.0, 4830000.0, 0.0])
    las = laspy.LasData(header)
    order = np.argsort(np.round(y / 2.0) * 1000 + x)  # scan-line order, as a sensor writes
    las.x, las.y, las.z = 630000 + x[order], 4830000 + y[order], z[order]
    las.intensity = rng.integers(0, 4096, n).astype(np.uint16)
    las.return_number = np.ones(n, dtype=np.uint8)
    las.number_of_returns = np.ones(n, dtype=np.uint8)
    las.classification = np.full(n, 2, dtype=np.uint8)
    las.gps_time = 1e5 + np.arange(n) * 1e-5
    las.write(path)


def test_a_second_survey_is_at_most_twice_the_input(tmp_path):
    ref, cmp_ = tmp_path / "a.laz", tmp_path / "b.laz"
    _survey(ref, 1, 0.0)
    _survey(cmp_, 2, 0.25)
    out = run(tmp_path, ref, cmp_, "--normal-scale", "3", "--projection-scale", "2", "--max-depth", "2")
    assert out.stat().st_size <= 2 * ref.stat().st_size, (out.stat().st_size, ref.stat().st_size)


def test_autzen_output_is_at_most_twice_the_input(tmp_path, shared_data):
    pair = shared_data / "pairs" / "autzen-bmx"
    ref = pair / "autzen-bmx-2010.las"
    out = run(tmp_path, ref, pair / "autzen-bmx-2023.las", "--normal-scale", "3", "--projection-scale", "2",
              "--max-depth", "5")
    assert out.stat().st_size <= 2 * same_points_laz(ref, read_cloud(out).xyz)


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("pair")
    ref, cmp_ = tmp / "a.laz", tmp / "b.laz"
    _survey(ref, 3, 0.0)
    _survey(cmp_, 4, 0.5)
    return ref, cmp_


def _result(ref, cmp_):
    return m3c2kit.compare(read_cloud(ref), read_cloud(cmp_), normal_scale=3.0, projection_scale=2.0,
                           max_depth=2.0, orient="+z")


def test_laz_columns_read_back_within_the_bound_with_nan_kept(tmp_path, pair):
    ref, cmp_ = pair
    out = run(tmp_path, ref, cmp_, "--normal-scale", "3", "--projection-scale", "2", "--max-depth", "2")
    want = _result(ref, cmp_).columns()
    got = read_cloud(out)
    assert set(COMPACT) <= set(got.fields) and "nx" not in got.fields and "sigma1" not in got.fields
    assert got.fields["intensity"].dtype == np.uint16  # the core points' own attributes carried
    for name in COMPACT:
        a, b = np.asarray(want[name], dtype=np.float64), got.fields[name]
        np.testing.assert_array_equal(np.isnan(a), np.isnan(b), err_msg=name)
        ok = ~np.isnan(a)
        assert np.max(np.abs(a[ok] - b[ok])) <= (BOUND * max(1.0, np.max(np.abs(a[ok]))) if name in ("distance", "lod")
                                                 else 0.0), name
    assert np.isnan(want["distance"]).any() and np.isnan(want["n1"]).sum() < len(want["n1"])
    # laspy: the raw integers, the scale and the declared no_data
    las = laspy.read(out)
    dims = {d.name: d for d in las.point_format.extra_dimensions}
    assert dims["distance"].dtype == np.int32 and float(dims["distance"].scales[0]) == LENGTH_QUANTUM
    record = {s.name.rstrip(b"\0").decode(): s
              for v in las.header.vlrs.get("ExtraBytesVlr") for s in v.extra_bytes_structs}
    no_data = record["distance"].no_data[0]
    assert record["distance"].options & record["distance"].NO_DATA_BIT_MASK
    raw = las.points.array["distance"]
    np.testing.assert_array_equal(raw == no_data, np.isnan(want["distance"]))
    ok = raw != no_data
    np.testing.assert_allclose(np.asarray(las["distance"])[ok], want["distance"][ok], rtol=0, atol=BOUND)
    assert las.points.array["n1"].dtype == np.uint32 and las.points.array["significant"].dtype == np.uint8


@pytest.mark.slow
def test_all_fields_and_float64(tmp_path, pair):
    ref, cmp_ = pair
    common = ["--normal-scale", "3", "--projection-scale", "2", "--max-depth", "2"]
    want = _result(ref, cmp_).columns()
    got = read_cloud(run(tmp_path, ref, cmp_, *common, "--all-fields", name="all.laz")).fields
    for name in ("nx", "ny", "nz"):
        ok = ~np.isnan(want[name])
        assert np.max(np.abs(got[name][ok] - want[name][ok])) <= 0.5 * UNIT_QUANTUM * (1 + 1e-9)
    for name in ("sigma1", "sigma2", "normal_scale", "roughness"):
        np.testing.assert_array_equal(np.isnan(got[name]), np.isnan(want[name]))
        ok = ~np.isnan(want[name])
        assert np.max(np.abs(got[name][ok] - want[name][ok])) <= BOUND * max(1.0, np.max(want[name][ok]))
    exact = read_cloud(run(tmp_path, ref, cmp_, *common, "--all-fields", "--float64", name="f64.laz")).fields
    for name in ("distance", "lod", "sigma1", "nx", "roughness"):
        assert exact[name].dtype == np.float64
        np.testing.assert_array_equal(exact[name], want[name])


@pytest.mark.slow
def test_field_names_and_text_outputs(tmp_path, pair):
    ref, cmp_ = pair
    common = ["--normal-scale", "3", "--projection-scale", "2", "--max-depth", "2"]
    cc = read_cloud(run(tmp_path, ref, cmp_, *common, "--field-names", "cloudcompare", name="cc.laz")).fields
    assert {"M3C2 distance", "distance uncertainty", "significant change", "Npoints_cloud1"} <= set(cc)
    want = _result(ref, cmp_).columns()
    for name in ("out.csv", "out.ply"):
        table = read_cloud(run(tmp_path, ref, cmp_, *common, name=name)).fields
        assert {"nx", "sigma1", "roughness", *COMPACT} <= set(table)  # text and PLY: every column
        np.testing.assert_array_equal(table["distance"].astype(np.float32), want["distance"].astype(np.float32))


def test_a_length_beyond_int32_stays_float32():
    from m3c2kit.io.quantised import Quantised, quantised
    assert isinstance(quantised(np.array([1.0, np.nan, -2.5]), "length"), Quantised)
    far = quantised(np.array([1.0, 3e5]), "length")  # 3e5 / 1e-4 > 2**31
    assert not isinstance(far, Quantised) and far.dtype == np.float32
    assert not isinstance(quantised(np.array([1.5]), "count"), Quantised)


@pytest.mark.parametrize("value", [1e39, -3.5e38, 1e300, 1e-39, -1e-300])
def test_a_value_float32_cannot_hold_is_refused_not_stored_as_inf_or_zero(value):
    """Issue 42: an LOD of 1e71 (a huge alignment covariance) was written as inf, with only numpy's
    overflow warning; a value below float32's normals loses its digits or becomes 0."""
    from m3c2kit.base.errors import CloudWriteError
    from m3c2kit.io.quantised import as_float32, quantised
    if abs(value) > 1:  # too large for int32 steps of 0.1 mm too (a tiny one is quantised to 0 there, by design)
        with pytest.raises(CloudWriteError, match=r"^out\.las: column 'lod' holds .*float32 cannot store.*--float64$"):
            quantised(np.array([1.0, value]), "length", "out.las: column 'lod'")
    with pytest.raises(CloudWriteError, match="float32 cannot store"):
        as_float32(np.array([value, np.nan]), "x")
    edge = np.array([0.0, np.inf, -np.inf, np.nan, 3.4e38, -1.2e-38])  # 0, inf, NaN and the limits are kept
    np.testing.assert_array_equal(as_float32(edge, "x"), edge.astype(np.float32))
