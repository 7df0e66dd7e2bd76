"""CRS handling through pyproj (m3c2kit.io.crs, io.describe): equality of real ESRI and OGC WKTs,
names and units, the checks compare runs, --crs texts, and `m3c2 info` data.

tests/data/crs/*.wkt are real WKT records of LAS files (PROVENANCE.md there)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from m3c2kit.base.errors import UsageError
from m3c2kit.io import Cloud, write_cloud_table
from m3c2kit.io import crs as C
from m3c2kit.io.describe import describe, describe_text

DATA = Path(__file__).resolve().parents[3] / "tests" / "data"
OGC_2994 = (DATA / "crs" / "autzen-ogc.wkt").read_text()
ESRI_2994 = (DATA / "crs" / "autzen_trim.wkt").read_text()
ESRI_2992 = (DATA / "crs" / "interesting-esri.wkt").read_text()


def test_esri_and_ogc_wkt_of_one_crs_are_equal():
    # The two spellings differ in names, TOWGS84 and the last digits of the false easting.
    assert ESRI_2994 != OGC_2994
    assert C.same_crs(ESRI_2994, OGC_2994) is True and C.same_crs(OGC_2994, ESRI_2994) is True
    assert C.same_crs(ESRI_2994, "EPSG:2994") is True
    assert C.same_crs(ESRI_2992, "EPSG:2992") is True
    # Another datum (NAD83 vs NAD83(HARN)), same projection and units: different CRSs.
    assert C.same_crs(ESRI_2992, OGC_2994) is False and C.same_crs(ESRI_2992, ESRI_2994) is False
    assert C.same_crs("EPSG:32617", "EPSG:26917") is False  # WGS 84 vs NAD83 UTM 17N


def test_names_codes_and_units_come_from_proj():
    assert C.crs_label(OGC_2994) == "'NAD83(HARN) / Oregon Lambert (ft)' (EPSG:2994)"
    assert C.crs_label(ESRI_2992) == "'NAD83 / Oregon GIC Lambert (ft)' (EPSG:2992)"
    assert C.crs_label("EPSG:32617") == "'WGS 84 / UTM zone 17N' (EPSG:32617)"
    assert C.crs_label(None) == "unknown"
    assert C.crs_units(OGC_2994) == "foot" and C.crs_units("EPSG:32617") == "metre"
    assert C.crs_units("EPSG:6360") == "US survey foot"
    assert C.crs_units("EPSG:2992+5703") == "foot (horizontal), metre (vertical)"
    assert C.is_angular("EPSG:4326") and C.is_angular("EPSG:4979") and not C.is_angular("EPSG:32617")
    info = C.crs_info(ESRI_2992)
    assert info["name"] == "NAD83 / Oregon GIC Lambert (ft)" and info["epsg"] == 2992 and info["units"] == "foot"
    assert info["wkt"].startswith("PROJCRS[") and json.dumps(info)


def _cloud(crs=None, units=None, path=None):
    return Cloud(np.zeros((1, 3)), crs=crs, units_hint=units, path=path)


def test_check_crs_rules():
    ref = _cloud(ESRI_2994, "foot", "ref.las")
    C.check_crs(ref, _cloud(OGC_2994, "foot", "cmp.las"))  # same CRS, two spellings
    with pytest.raises(C.CrsMismatch, match="different CRSs: reference ref.las is in 'NAD_1983_HARN"):
        C.check_crs(ref, _cloud(ESRI_2992, "foot", "cmp.las"))
    with pytest.raises(C.CrsMismatch, match=r"only one cloud has a CRS: reference ref.las .* compared cmp.xyz has none"):
        C.check_crs(ref, _cloud(path="cmp.xyz"))
    with pytest.raises(C.CrsMismatch, match=r"only one cloud has a CRS: compared cmp.las .* reference ref.xyz has none"):
        C.check_crs(_cloud(path="ref.xyz"), _cloud(OGC_2994, path="cmp.las"))
    C.check_crs(ref, _cloud(path="cmp.xyz"), ignore=True)
    C.check_crs(ref, _cloud(OGC_2994), core=_cloud(path="core.txt"))  # core points take the reference's CRS
    with pytest.raises(C.CrsMismatch, match="core points core.las"):
        C.check_crs(ref, _cloud(OGC_2994), core=_cloud(ESRI_2992, path="core.las"))
    C.check_crs(_cloud(), _cloud())  # no CRS at all: nothing to compare
    geo = _cloud("EPSG:4326", "degree", "ref.las")
    with pytest.raises(C.CrsMismatch, match=r"angular coordinates .*WGS 84.*--allow-angular"):
        C.check_crs(geo, _cloud("EPSG:4326", "degree", "cmp.las"))
    C.check_crs(geo, _cloud("EPSG:4326", "degree"), allow_angular=True)
    C.check_crs(geo, _cloud("EPSG:4326", "degree"), ignore=True)
    # Degrees known from GeoTIFF keys only (no readable CRS text) are refused too.
    with pytest.raises(C.CrsMismatch, match="angular"):
        C.check_crs(_cloud(None, "degree", "a.las"), _cloud(None, "degree", "b.las"))


@pytest.mark.parametrize("junk", ["GEOGCS[" * 3000 + "]" * 3000, 'PROJCS["cut short', "not a crs at all"])
def test_an_unreadable_crs_is_refused_unless_ignored(junk):
    """Issue 42: a compared cloud whose CRS cannot be read (a WKT nested thousands deep) was compared
    with a reference that has one, without a word."""
    ref = _cloud(ESRI_2994, "foot", "ref.las")
    with pytest.raises(C.CrsMismatch, match=r"compared cmp.las: its CRS cannot be read .*--ignore-crs"):
        C.check_crs(ref, _cloud(junk, None, "cmp.las"))
    with pytest.raises(C.CrsMismatch, match=r"reference ref.las: its CRS cannot be read"):
        C.check_crs(_cloud(junk, None, "ref.las"), ref)
    C.check_crs(ref, _cloud(junk, None, "cmp.las"), ignore=True)


def test_reference_extent_is_computed_once_and_only_when_needed(monkeypatch):
    # `m3c2 series` checks one reference against every epoch: its extent (the sample points of a
    # CRS conversion) is computed only when a conversion needs it, and once per reference.
    calls = []
    nanmin = np.nanmin
    monkeypatch.setattr(np, "nanmin", lambda *a, **k: calls.append(1) or nanmin(*a, **k))
    ref = Cloud(np.random.default_rng(0).random((50, 3)), crs=None, path="ref.las")
    for _ in range(3):
        C.check_crs(ref, _cloud(path="cmp.las"))  # no CRS on either: nothing to convert
    assert calls == []

    def unneeded():
        raise AssertionError("the sample points were computed for two equal CRS texts")
    assert C.same_crs(OGC_2994, OGC_2994, unneeded) is True
    first = C._extent_corners(ref)
    assert np.array_equal(C._extent_corners(ref), first) and len(calls) == 1
    assert np.array_equal(first[0], ref.xyz[:, :2].min(axis=0)) and np.array_equal(first[3], ref.xyz[:, :2].max(axis=0))
    other = Cloud(ref.xyz + 1.0, crs=None, path="other.las")
    assert np.array_equal(C._extent_corners(other)[0], first[0] + 1.0) and len(calls) == 2


def test_assign_crs(tmp_path):
    wkt = C.assign_crs("EPSG:32617")
    assert wkt.startswith("PROJCRS[") and C.same_crs(wkt, "EPSG:32617")
    prj = tmp_path / "site.prj"
    prj.write_text(ESRI_2992)
    assert C.same_crs(C.assign_crs(str(prj)), "EPSG:2992")
    with pytest.raises(UsageError, match="--crs 'EPSG:99999999' is not a CRS PROJ can read"):
        C.assign_crs("EPSG:99999999")


def test_assigned_crs_travels_to_the_las_output(tmp_path):
    xyz = np.random.default_rng(1).uniform(0, 10, (20, 3)) + [630000, 4830000, 0]
    like = Cloud(xyz, crs=C.assign_crs("EPSG:32617"))
    write_cloud_table(tmp_path / "o.las", xyz, {"d": np.ones(20)}, like=like)
    d = describe(tmp_path / "o.las")
    assert d["crs"]["epsg"] == 32617 and d["crs"]["units"] == "metre"
    json.dumps(d)
    text = describe_text(d)
    assert "CRS:     WGS 84 / UTM zone 17N (EPSG:32617)" in text and "units:   metre" in text
    assert "PROJCRS" not in text and "{" not in text and "[" not in text


def test_without_pyproj_every_crs_is_unknown(monkeypatch):
    import sys
    monkeypatch.setitem(sys.modules, "pyproj", None)  # import pyproj now raises ImportError
    C.parse_crs.cache_clear()
    try:
        assert C.parse_crs(OGC_2994) is None
        assert C.same_crs(OGC_2994, ESRI_2992) is None and C.same_crs(OGC_2994, OGC_2994) is True
        assert C.crs_label("EPSG:2994") == "EPSG:2994" and C.crs_units(OGC_2994) is None
        # The same text (white space aside) passes; texts that differ need pyproj to be told apart.
        C.check_crs(_cloud(OGC_2994, path="a.las"), _cloud(" ".join(OGC_2994.split()), path="b.las"))
        with pytest.raises(C.CrsMismatch, match=r"a.las and compared b.las have CRS texts that differ.*"
                                                r"needs the crs extra \(pyproj\): pip install 'm3c2kit\[crs\]'"):
            C.check_crs(_cloud(OGC_2994, path="a.las"), _cloud(ESRI_2992, path="b.las"))
        C.check_crs(_cloud(OGC_2994, path="a.las"), _cloud(ESRI_2992, path="b.las"), ignore=True)
        assert C.crs_info(OGC_2994)["readable"] is False
        with pytest.raises(UsageError, match=r"needs the crs extra \(pyproj\): pip install 'm3c2kit\[crs\]'"):
            C.assign_crs("EPSG:32617")
    finally:
        C.parse_crs.cache_clear()


def test_a_crs_name_with_line_breaks_is_labelled_on_one_line():
    # Found by the crs_text fuzz target: a WKT's quoted name may hold a line break, which PROJ keeps.
    pytest.importorskip("pyproj")
    from m3c2kit.io.crs import crs_label
    wkt = ('GEOGCRS["WGS\n84",DATUM["World Geodetic System 1984",ELLIPSOID["WGS 84",6378137,298.257223563]],'
           'CS[ellipsoidal,2],AXIS["lat",north,ANGLEUNIT["degree",0.0174532925199433]],'
           'AXIS["lon",east,ANGLEUNIT["degree",0.0174532925199433]]]')
    assert crs_label(wkt) == "'WGS 84'"
