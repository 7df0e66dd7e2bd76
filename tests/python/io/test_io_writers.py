"""m3c2kit.io writers: LAS/LAZ/PLY/text round trips, CRS copying, atomic all-or-nothing output."""
from __future__ import annotations

import os
import stat

import laspy
import numpy as np
import pytest

import m3c2kit.io.ascii
import m3c2kit.io.ply
from m3c2kit.base.errors import CloudWriteError, QuantisationWarning
from m3c2kit.io import SUPPORTED_WRITE, Cloud, atomic_output, read_cloud, write_cloud_table


def _table(n: int = 500, seed: int = 0):
    rng = np.random.default_rng(seed)
    xyz = np.column_stack([rng.uniform(500_000, 500_200, n), rng.uniform(4_000_000, 4_000_300, n),
                           rng.uniform(-5, 120, n)])
    distance = rng.normal(0, 0.3, n)
    distance[::17] = np.nan
    fields = {
        "distance": distance,
        "lod": rng.uniform(0, 1, n).astype(np.float32),
        "significant": rng.integers(0, 2, n).astype(bool),
        "n1": rng.integers(0, 2000, n).astype(np.int64),
        "sigma1": rng.uniform(0, 1, n) * 1e-9,
        "status": rng.integers(0, 6, n).astype(np.uint8),
    }
    return xyz, fields


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return np.array_equal(np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64), equal_nan=True)


def _leftovers(directory) -> list[str]:
    return sorted(p.name for p in directory.iterdir())


# ------------------------------------------------------------------------------------- LAS

@pytest.mark.parametrize("ext", [".las", ".laz"])
def test_las_round_trip(tmp_path, ext):
    xyz, fields = _table()
    path = tmp_path / f"out{ext}"
    with pytest.warns(QuantisationWarning, match="scale 1e-06"):  # uniform float64 values: finer than 1e-6
        write_cloud_table(path, xyz, fields)
    las = laspy.read(path)
    assert str(las.header.version) == "1.4" and las.header.point_format.id == 6
    assert las.header.are_points_compressed == (ext == ".laz")
    types = {d.name: d.dtype for d in las.point_format.extra_dimensions}
    # Each field keeps its own numeric type (bool as uint8): io/las.py _extra_type.
    assert types == {"distance": np.float64, "lod": np.float32, "significant": np.uint8, "n1": np.int64,
                     "sigma1": np.float64, "status": np.uint8}
    # Spans of at most 301 from floor(min): 1e-6 is the finest decimal scale int32 holds.
    np.testing.assert_allclose(las.header.scales, 1e-6)
    np.testing.assert_array_equal(las.header.offsets, np.floor(xyz.min(axis=0)))
    back = read_cloud(path)
    assert np.abs(back.xyz - xyz).max() <= 0.5e-6 + 1e-9
    for name, values in fields.items():
        assert _same(back.fields[name], values), name


def test_las_uses_like_scale_offset_and_copies_wkt(shared_data, tmp_path):
    src = read_cloud(shared_data / "readers" / "laspy" / "file_with_both_wkt_and_geotiff_vlrs.las")
    distance = np.linspace(-1, 1, len(src))
    path = tmp_path / "change.laz"
    write_cloud_table(path, src.xyz, {"distance": distance}, like=src)
    las = laspy.read(path)
    assert tuple(las.header.scales) == src.scale and tuple(las.header.offsets) == src.offset
    assert las.header.global_encoding.wkt
    wkt = [v for v in las.header.vlrs if isinstance(v, laspy.vlrs.known.WktCoordinateSystemVlr)]
    assert len(wkt) == 1 and wkt[0].string.rstrip("\0") == src.crs
    back = read_cloud(path)
    assert back.crs == src.crs and back.units_hint == "US survey foot"
    # Same scale and offset: the quantised coordinates come back exactly.
    np.testing.assert_array_equal(back.xyz, src.xyz)
    np.testing.assert_array_equal(back.fields["distance"], distance)


def test_las_copies_liblas_wkt_and_geotiff_keys(shared_data, tmp_path):
    liblas = read_cloud(shared_data / "readers" / "laspy" / "autzen_geo_proj.las")
    out = tmp_path / "a.las"
    write_cloud_table(out, liblas.xyz, {}, like=liblas)
    assert read_cloud(out).crs == liblas.crs
    geotiff = read_cloud(shared_data / "readers" / "pdal" / "las" / "test_utm17.las")  # no WKT at all
    out = tmp_path / "g.las"
    write_cloud_table(out, geotiff.xyz, {}, like=geotiff)
    written = {(v.user_id, v.record_id) for v in laspy.read(out).header.vlrs}
    assert ("LASF_Projection", 34735) in written
    assert read_cloud(out).crs == "EPSG:32617"


def test_las_fields_from_a_las_go_back_into_standard_dimensions(shared_data, tmp_path):
    src = read_cloud(shared_data / "readers" / "laspy" / "simple.las")  # PF3: has red/green/blue
    out = tmp_path / "copy.las"
    write_cloud_table(out, src.xyz, src.fields, like=src)
    las = laspy.read(out)
    assert las.header.point_format.id == 7
    extra = set(las.point_format.extra_dimension_names)
    assert "intensity" not in extra and "red" not in extra and "scan_angle_rank" in extra
    back = read_cloud(out)
    np.testing.assert_array_equal(back.xyz, src.xyz)
    for name, values in src.fields.items():
        assert _same(back.fields[name], values), name


def test_las_refuses_what_it_cannot_store(tmp_path):
    xyz, _ = _table(10)
    like = Cloud(xyz, scale=(0.001, 0.001, 0.001), offset=(0.0, 0.0, 0.0))
    far = xyz.copy()
    far[3, 0] = 3e6  # 3e9 after scaling: past int32
    path = tmp_path / "far.las"
    with pytest.raises(CloudWriteError, match=r"x coordinates .* do not fit LAS scale") as err:
        write_cloud_table(path, far, {}, like=like)
    assert str(err.value).startswith(f"{path}: ")
    bad = xyz.copy()
    bad[2, 1] = np.nan
    with pytest.raises(CloudWriteError, match=r"non-finite coordinates \(1 points\)"):
        write_cloud_table(path, bad, {})
    with pytest.raises(CloudWriteError, match="does not fit the LAS uint16"):
        write_cloud_table(path, xyz, {"intensity": np.full(10, 70000.0)})
    with pytest.raises(CloudWriteError, match="1 to 32 characters"):
        write_cloud_table(path, xyz, {"n" * 33: np.zeros(10)})
    assert _leftovers(tmp_path) == []


# ------------------------------------------------------------------------------- PLY, text

def test_ply_round_trip_is_exact(tmp_path):
    xyz, fields = _table()
    fields["i8"] = np.arange(len(xyz), dtype=np.int8)
    path = tmp_path / "out.ply"
    write_cloud_table(path, xyz, fields)
    head = path.read_bytes()[:400].decode("ascii", "replace")
    assert "format binary_little_endian 1.0" in head and "property double x" in head
    assert "property float lod" in head and "property uchar significant" in head
    assert "property int n1" in head  # int64 stored as int32 when the values fit
    back = read_cloud(path)
    np.testing.assert_array_equal(back.xyz, xyz)
    for name, values in fields.items():
        assert _same(back.fields[name], values), name
    assert back.fields["lod"].dtype == np.float32 and back.fields["i8"].dtype == np.int8


@pytest.mark.parametrize("ext", [".csv", ".txt", ".xyz", ".asc"])
def test_text_round_trip_is_exact(tmp_path, ext):
    xyz, fields = _table()
    # Doubles that a fixed %.15g would not preserve, and extremes.
    xyz[:6, 2] = [0.1 + 0.2, 1 / 3, 5e-324, 1.7976931348623157e308, -0.0, 2.0**53 + 1]
    path = tmp_path / f"out{ext}"
    write_cloud_table(path, xyz, fields)
    first = path.read_text().splitlines()[0]
    sep = "," if ext == ".csv" else " "
    assert first == sep.join(["x", "y", "z", *fields])
    back = read_cloud(path)
    np.testing.assert_array_equal(back.xyz, xyz)
    assert np.signbit(back.xyz[4, 2])
    for name, values in fields.items():
        assert _same(back.fields[name], values), name


def test_text_writer_is_chunked_and_compact(tmp_path, monkeypatch):
    monkeypatch.setattr(m3c2kit.io.ascii, "_CHUNK", 7)
    xyz = np.array([[0.5, 1.0, 2.25]] * 20)
    path = tmp_path / "c.csv"
    write_cloud_table(path, xyz, {"w": np.arange(20, dtype=np.uint16)})
    lines = path.read_text().splitlines()
    assert len(lines) == 21 and lines[1] == "0.5,1.0,2.25,0" and lines[-1] == "0.5,1.0,2.25,19"


def test_writer_argument_errors(tmp_path):
    xyz, _ = _table(5)
    with pytest.raises(CloudWriteError, match=r"cannot write '\.e57' files"):
        write_cloud_table(tmp_path / "x.e57", xyz, {})
    with pytest.raises(CloudWriteError, match=r"points must have shape \(N, 3\)"):
        write_cloud_table(tmp_path / "x.csv", xyz[:, :2], {})
    with pytest.raises(CloudWriteError, match=r"field 'd' has shape \(4,\)"):
        write_cloud_table(tmp_path / "x.csv", xyz, {"d": np.zeros(4)})
    with pytest.raises(CloudWriteError, match="reserved for coordinates"):
        write_cloud_table(tmp_path / "x.ply", xyz, {"x": np.zeros(5)})
    with pytest.raises(CloudWriteError, match="cannot be written as a text column name"):
        write_cloud_table(tmp_path / "x.csv", xyz, {"a,b": np.zeros(5)})
    assert _leftovers(tmp_path) == []
    assert set(SUPPORTED_WRITE) >= {".las", ".laz", ".ply", ".csv", ".txt"}


# ---------------------------------------------------------------------------------- atomic

@pytest.mark.parametrize("ext", [".las", ".laz", ".ply", ".csv"])
def test_no_partial_file_when_the_writer_fails_midway(tmp_path, monkeypatch, ext):
    xyz, fields = _table(100)

    def half_then_fail(target):
        if isinstance(target, (str, os.PathLike)):
            with open(target, "wb") as f:
                f.write(b"partial data" * 100)
        else:
            target.write(b"partial data" * 100)
        raise RuntimeError("disk on fire")

    if ext in (".las", ".laz"):
        monkeypatch.setattr(laspy.LasData, "write", lambda self, dest, **kw: half_then_fail(dest))
    elif ext == ".ply":
        monkeypatch.setattr(m3c2kit.io.ply, "atomic_output", _failing_atomic(half_then_fail))
    else:
        monkeypatch.setattr(m3c2kit.io.ascii, "_CHUNK", 10)
        calls = {"n": 0}
        real_column = m3c2kit.io.ascii._text_column

        def fail_on_third_chunk(values):
            calls["n"] += 1
            if calls["n"] > 2 * (3 + len(fields)):
                raise RuntimeError("disk on fire")
            return real_column(values)

        monkeypatch.setattr(m3c2kit.io.ascii, "_text_column", fail_on_third_chunk)
    path = tmp_path / f"out{ext}"
    with pytest.raises(CloudWriteError, match="disk on fire"):
        write_cloud_table(path, xyz, fields)
    assert _leftovers(tmp_path) == []


def _failing_atomic(fail):
    """atomic_output whose body writes part of the file and then raises."""
    from contextlib import contextmanager

    @contextmanager
    def wrapper(path):
        with atomic_output(path) as tmp:
            fail(tmp)
            yield tmp

    return wrapper


def test_failed_write_keeps_the_previous_file(tmp_path):
    path = tmp_path / "keep.csv"
    path.write_text("old content\n")
    with pytest.raises(ValueError):
        with atomic_output(path) as tmp:
            tmp.write_text("new, half written")
            raise ValueError("boom")
    assert path.read_text() == "old content\n"
    assert _leftovers(tmp_path) == ["keep.csv"]


def test_atomic_output_replaces_and_sets_normal_permissions(tmp_path):
    path = tmp_path / "new.csv"
    with atomic_output(path) as tmp:
        # In a private folder beside the target (0700), reached through its held descriptor (the
        # pinned /proc/self/fd path, io/private.py), not carrying a name a glob there matches.
        private = [p for p in tmp_path.iterdir() if p.name.startswith(".m3c2-tmp-")]
        assert len(private) == 1 and os.path.samefile(tmp.parent, private[0])
        assert stat.S_IMODE(tmp.parent.stat().st_mode) == 0o700 and not list(tmp_path.glob("*.csv"))
        tmp.write_text("1,2,3\n")
    assert path.read_text() == "1,2,3\n" and _leftovers(tmp_path) == ["new.csv"]
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~umask


def test_unwritable_destinations(tmp_path):
    xyz, fields = _table(5)
    a_file = tmp_path / "not_a_dir"
    a_file.write_text("x")
    # Tests run as root, for whom chmod does not block writing: use a path whose parent is a file.
    under_file = a_file / "out.las"
    with pytest.raises(CloudWriteError, match="is not a directory") as err:
        write_cloud_table(under_file, xyz, fields)
    assert str(err.value).startswith(f"{under_file}: ")
    missing = tmp_path / "missing" / "out.csv"
    with pytest.raises(CloudWriteError, match="does not exist") as err:
        write_cloud_table(missing, xyz, fields)
    assert str(err.value).startswith(f"{missing}: ")
    a_dir = tmp_path / "out.ply"
    a_dir.mkdir()
    with pytest.raises(CloudWriteError, match="is a directory") as err:
        write_cloud_table(a_dir, xyz, fields)
    assert str(err.value).startswith(f"{a_dir}: ")
    assert _leftovers(tmp_path) == ["not_a_dir", "out.ply"] and _leftovers(a_dir) == []
