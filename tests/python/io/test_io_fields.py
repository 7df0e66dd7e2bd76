"""Output field names (m3c2kit / CloudCompare / PDAL), stored types, and the core points' own
attributes carried to the output (m3c2kit.io.fields, m3c2kit.write)."""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

import m3c2kit
from m3c2kit.io.quantised import LENGTH_QUANTUM
from m3c2kit.base.errors import UsageError
from m3c2kit.io import fields as F
from m3c2kit.engine import match_rows

REPO = Path(__file__).resolve().parents[3]
AUTZEN = REPO / "tests" / "data" / "pairs" / "autzen-bmx"
TORONTO = REPO / "data" / "toronto-ttp"


def _header(path: Path) -> list[str]:
    with open(path, newline="") as f:
        return next(csv.reader(f))


def test_peer_names_are_the_peers_own():
    # The names CloudCompare and PDAL wrote in their outputs for the autzen pair.
    cc, pdal = _header(AUTZEN / "autzen-bmx-cc.txt"), _header(AUTZEN / "autzen-bmx-m3c2.txt")
    for f in F.FIELDS:
        if f.cloudcompare and f.cloudcompare != "normal scale":  # written only by multi-scale runs
            assert f.cloudcompare in cc, f.cloudcompare
        if f.pdal:
            assert f.pdal in pdal, f.pdal
    assert {f.cloudcompare for f in F.FIELDS} >= {"M3C2 distance", "distance uncertainty", "significant change",
                                                 "Npoints_cloud1", "Npoints_cloud2", "STD_cloud1", "STD_cloud2",
                                                 "normal scale"}
    assert F.output_name("lod", "cloudcompare") == "distance uncertainty"
    assert F.output_name("lod", "cloudcompare", spaces=False) == "distance_uncertainty"
    assert F.output_name("n1", "pdal") == "m3c2_count1" and F.output_name("status", "pdal") == "status"
    with pytest.raises(UsageError, match="--field-names must be one of m3c2, cloudcompare, pdal"):
        F.output_name("lod", "qgis")


def test_docs_table_is_generated_from_the_code_table():
    assert F.markdown_table() in (REPO / "docs" / "python.md").read_text()


@pytest.fixture(scope="module")
def toronto():
    ref, cmp_ = m3c2kit.read(TORONTO / "TTP_15.laz"), m3c2kit.read(TORONTO / "TTP_23.laz")
    r = m3c2kit.compare(ref, cmp_, core_spacing=4, normal_scale=10, projection_scale=5, max_depth=10)
    return ref, r


def test_las_output_types_names_and_carried_attributes(toronto, tmp_path):
    ref, r = toronto
    out = tmp_path / "cc.laz"
    m3c2kit.write(out, r, like=ref, field_names="cloudcompare")
    back = m3c2kit.read(out)
    np.testing.assert_array_equal(back.xyz, r.core)
    # LAS storage: integers at 0.1 mm (m3c2kit.io.quantised), at most 0.05 mm off, NaN kept.
    d = back.fields["M3C2 distance"]
    ok = np.isfinite(r.distance)
    assert np.array_equal(np.isnan(d), ~ok)
    assert np.all(np.abs(d[ok] - r.distance[ok]) <= 0.5 * LENGTH_QUANTUM + 1e-12)
    assert back.fields["status"].dtype == np.uint8
    # NaN where no cylinder was searched (never a 0 that reads as an empty cylinder).
    np.testing.assert_array_equal(back.fields["Npoints_cloud2"], r.columns()["n2"])
    # The core points are a subsample of the reference: its attributes follow them, in the LAS
    # standard dimensions (not zeros).
    index = match_rows(ref.xyz, r.core)
    for name in ("intensity", "classification", "gps_time", "return_number", "point_source_id"):
        np.testing.assert_array_equal(back.fields[name], ref.fields[name][index], err_msg=name)
    assert back.fields["intensity"].any() and back.fields["gps_time"].any()
    wide = tmp_path / "wide.laz"
    m3c2kit.write(wide, r, like=ref, float64=True)
    w = m3c2kit.read(wide)
    assert w.fields["distance"].dtype == np.float64
    np.testing.assert_array_equal(w.fields["distance"], r.distance)


@pytest.mark.slow
def test_laz_size_float32_against_float64(toronto, tmp_path):
    """Measured (docs/python.md): the default LAZ (CloudCompare's columns as 0.1 mm integers) is
    under twice the input, a fraction of the float64 one (tests/python/output/test_output_size.py
    checks the 2x on more inputs)."""
    ref, _ = toronto
    cmp_ = m3c2kit.read(TORONTO / "TTP_23.laz")
    r = m3c2kit.compare(ref, cmp_, normal_scale=10, projection_scale=5, max_depth=10)  # every point a core point
    small, wide = tmp_path / "f32.laz", tmp_path / "f64.laz"
    m3c2kit.write(small, r, like=ref)
    m3c2kit.write(wide, r, like=ref, float64=True)
    size_in = (TORONTO / "TTP_15.laz").stat().st_size
    assert small.stat().st_size < 0.6 * wide.stat().st_size
    assert small.stat().st_size < 2 * size_in


def test_text_output_names_without_spaces_and_core_file_attributes(tmp_path):
    ref = m3c2kit.read(AUTZEN / "autzen-bmx-2010.las")
    cmp_ = m3c2kit.read(AUTZEN / "autzen-bmx-2023.las")
    core = ref.select(np.arange(len(ref)) % 9 == 0)
    core_file = tmp_path / "core.laz"
    # A core file written in another order: attributes are matched by coordinates.
    order = np.random.default_rng(3).permutation(len(core))
    m3c2kit.io.write_cloud_table(core_file, core.xyz[order], {k: v[order] for k, v in core.fields.items()}, like=ref)
    core_cloud = m3c2kit.read(core_file)
    r = m3c2kit.compare(ref, cmp_, core_cloud, normal_scale=2.780864, projection_scale=5.780864, max_depth=5.5)
    out = tmp_path / "o.csv"
    m3c2kit.write(out, r, like=core_cloud, field_names="cloudcompare")
    head = _header(out)
    assert "M3C2_distance" in head and "distance_uncertainty" in head and "Npoints_cloud1" in head
    rows = np.genfromtxt(out, delimiter=",", names=True)
    np.testing.assert_array_equal(rows["Intensity" if "Intensity" in head else "intensity"],
                                  core.fields["intensity"][order])
    # Core points not among the given cloud's points: nothing carried, nothing made up.
    moved = m3c2kit.compare(ref, cmp_, core.xyz + 0.001, normal_scale=2.780864, projection_scale=5.780864,
                            max_depth=5.5)
    m3c2kit.write(tmp_path / "m.csv", moved, like=ref)
    assert "intensity" not in _header(tmp_path / "m.csv")


def test_attribute_named_like_a_column_is_prefixed():
    cloud = m3c2kit.Cloud(np.eye(3), {"distance": np.arange(3.0), "intensity": np.arange(3)})
    got = F.core_attributes(cloud, np.array([2, 0]), {"distance"})
    assert set(got) == {"core_distance", "intensity"}
    np.testing.assert_array_equal(got["intensity"], [2, 0])
