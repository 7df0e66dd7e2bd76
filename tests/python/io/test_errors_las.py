"""docs/errors.md, "LAS point counts" and "LAS scale" (issue 15, points 7 and 4): a header that
hides points, a LAZ header claiming far more points than its chunks hold, and LAS output from
inputs without a LAS scale (the fixed 0.001 put a laboratory scan's 2,000 core points at one
position)."""
from __future__ import annotations

import struct
import tracemalloc
import warnings

import laspy
import numpy as np
import pytest

from m3c2kit.cli.main import main
from m3c2kit.base.errors import CloudReadError, QuantisationWarning
from m3c2kit.io import read_cloud, write_cloud_table
from m3c2kit.io.las import choose_scale_offset


def patched_count(src, dst, count: int):
    """A copy of `src` whose header declares `count` points (legacy field, and LAS 1.4's 64-bit one)."""
    data = bytearray(src.read_bytes())
    minor = data[25]
    struct.pack_into("<I", data, 107, count if count < 2**32 and minor < 4 else 0)
    if minor >= 4:
        struct.pack_into("<Q", data, 247, count)
    dst.write_bytes(bytes(data))
    return dst


@pytest.mark.parametrize("name, real", [("laspy/simple.las", 1065), ("laspy/test1_4.las", 1000)])
def test_a_las_header_counting_fewer_points_than_its_records_is_refused(shared_data, tmp_path, name, real):
    """laspy read only the counted points: 65 of 1065 lost without a word."""
    bad = patched_count(shared_data / "readers" / name, tmp_path / "fewer.las", real - 65)
    with pytest.raises(CloudReadError) as err:
        read_cloud(bad)
    message = str(err.value)
    assert message.startswith(f"{bad}: the header declares {real - 65} points but the file holds {real} point "
                              f"records of ")
    assert "65 points would be lost" in message


def test_laz_claiming_1e8_points_is_refused_at_once(shared_data, tmp_path, capsys, monkeypatch):
    """A LAZ claiming 10^8 points in a 545 KB file was refused only after 7.9 s and 2.7 GB."""
    monkeypatch.setenv("M3C2_AVAILABLE_MEMORY", str(2**40))  # the memory guard must not be what refuses
    bad = patched_count(shared_data / "readers/laspy/autzen_trim.laz", tmp_path / "claims.laz", 10**8)
    tracemalloc.start()
    try:
        with pytest.raises(CloudReadError) as err:
            read_cloud(bad)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert str(err.value).startswith(f"{bad}: the header declares 100000000 points but the file holds 3 LASzip "
                                     f"chunks of at most 50000 points (at most 150000 points in ")
    assert peak < 10 * 2**20  # refused from the header, before any decompression
    assert main(["info", str(bad)]) == 1
    assert "declares 100000000 points" in capsys.readouterr().err


def test_laz_header_counting_fewer_points_than_its_chunks_is_refused(shared_data, tmp_path):
    bad = patched_count(shared_data / "readers/laspy/autzen_trim.laz", tmp_path / "fewer.laz", 90_000)
    with pytest.raises(CloudReadError, match=r"declares 90000 points but the file holds 3 LASzip chunks of 50000 "
                                             r"points \(more than 100000 points\)"):
        read_cloud(bad)


def test_every_shared_las_file_passes_the_count_checks(shared_data):
    """The checks refuse no legitimate file (COPC, EVLRs, waveform, padding, LAS 1.0-1.4)."""
    for path in sorted((shared_data / "readers").rglob("*.la[sz]")):
        if "broken" in path.parent.name or path.name in ("bad_vlr_count.las", "garbage_nVariableLength.las",
                                                         "1.2-with-color-clipped.las", "1.2-no-points.las",
                                                         "simple-laszip-compressor-version-1.2r0.laz"):
            continue
        from m3c2kit.io.las_header import check_las_file
        check_las_file(path)


# ------------------------------------------------------------------------------- LAS scale

def lab_scan(n=2000, seed=0):
    """A 2 mm-wide laboratory scan in metres, points 45 um apart on average, written as text
    with 9 decimals (a scanner's resolution): no LAS scale of its own."""
    rng = np.random.default_rng(seed)
    return np.round(np.column_stack([rng.uniform(0.101, 0.103, n), rng.uniform(0.2, 0.202, n),
                                     rng.uniform(0.05, 0.0502, n)]), 9)


def test_a_laboratory_scans_2000_core_points_stay_distinct(tmp_path):
    ref = lab_scan()
    np.savetxt(tmp_path / "ref.xyz", ref, fmt="%.9f")
    np.savetxt(tmp_path / "cmp.xyz", ref + [0, 0, 1e-5], fmt="%.9f")
    out = tmp_path / "change.laz"
    with warnings.catch_warnings():
        warnings.simplefilter("error", QuantisationWarning)  # nothing is lost: no warning
        assert main(["compare", str(tmp_path / "ref.xyz"), str(tmp_path / "cmp.xyz"), "-o", str(out),
                     "--normal-scale", "0.0005", "--projection-scale", "0.0003", "--max-depth", "0.0001",
                     "--quiet"]) == 0
    las = laspy.read(out)
    xyz = np.column_stack([las.x, las.y, las.z])
    assert len(np.unique(xyz, axis=0)) == 2000  # with scale 0.001: 4 positions
    assert las.header.scales[0] == 1e-10
    np.testing.assert_allclose(np.sort(xyz, axis=0), np.sort(ref, axis=0), rtol=0, atol=1e-12)


@pytest.mark.parametrize("lo, hi, scale", [
    ((0.1, 0.2, 0.05), (0.103, 0.202, 0.0502), 1e-10),    # laboratory scan: floor(min) = 0, span 0.202
    ((500_000, 5_000_000, 0), (501_000, 5_001_000, 50), 1e-6),  # 1 km at UTM coordinates
    ((500_000, 5_000_000, 0), (530_000, 5_001_000, 50), 1e-4),  # 30 km: 1e-5 would overflow int32
    ((-5.5, 0, 0), (2147.0, 1, 1), 1e-5),                  # 2153 from -6: just beyond 1e-6
    ((0, 0, 0), (0, 0, 0), 1e-3),                          # nothing to resolve
])
def test_the_scale_is_the_finest_decimal_that_int32_holds(lo, hi, scale):
    got, offset = choose_scale_offset(lo, hi)
    assert got == (scale,) * 3
    assert offset == tuple(float(np.floor(v)) for v in lo)
    assert max(np.subtract(hi, offset)) / scale <= 2**31 - 1


def test_survey_coordinates_keep_their_millimetres_without_a_warning(tmp_path):
    rng = np.random.default_rng(2)
    xyz = np.round(np.column_stack([rng.uniform(5e5, 5.3e5, 500), rng.uniform(5e6, 5.001e6, 500),
                                    rng.uniform(0, 50, 500)]), 3)
    with warnings.catch_warnings():
        warnings.simplefilter("error", QuantisationWarning)
        write_cloud_table(tmp_path / "survey.las", xyz, {})
    back = read_cloud(tmp_path / "survey.las").xyz
    assert np.abs(back - xyz).max() < 1e-8


def test_quantising_beyond_what_the_data_resolve_is_said(tmp_path):
    rng = np.random.default_rng(3)
    xyz = np.column_stack([rng.uniform(5e5, 5.3e5, 500), rng.uniform(5e6, 5.001e6, 500), rng.uniform(0, 50, 500)])
    out = tmp_path / "survey.laz"
    with pytest.warns(QuantisationWarning) as caught:
        write_cloud_table(out, xyz, {})
    message = str(caught[0].message)
    assert message.startswith(f"{out}: LAS stores the coordinates at scale 0.0001, the finest at which its int32 "
                              f"counts span ")
    assert "they move by up to 5e-05" in message or "they move by up to 4.9" in message
    assert read_cloud(out).scale == (1e-4,) * 3


def test_float32_coordinates_are_not_said_to_lose_precision(tmp_path):
    xyz = np.random.default_rng(4).uniform(0, 100, (300, 3)).astype(np.float32).astype(np.float64)
    with warnings.catch_warnings():
        warnings.simplefilter("error", QuantisationWarning)
        write_cloud_table(tmp_path / "f32.las", xyz, {})


def _patched_header(src, dst, offset: int, fmt: str, value) -> None:
    data = bytearray(src.read_bytes())
    struct.pack_into(fmt, data, offset, value)
    dst.write_bytes(bytes(data))


@pytest.mark.parametrize("offset, fmt, value, words", [
    (104, "<B", 99, "unknown LAS point format 35 (header byte 99"),  # was only "PATH: 35"
    (104, "<B", 11, "unknown LAS point format 11"),
    (147, "<d", 0.0, "its z scale factor is 0.0: every z would read as the offset"),  # z read as 0, exit 0
    (131, "<d", float("nan"), "its x scale factor is nan"),
    (139, "<d", float("inf"), "its y scale factor is inf"),
])
def test_a_las_header_of_an_impossible_format_or_scale_is_refused(tmp_path, capsys, offset, fmt, value, words):
    """Issue 42: point format 99 said only 'PATH: 35'; a z scale of 0 was accepted."""
    src = tmp_path / "ok.las"
    xyz = np.random.default_rng(3).uniform(0, 10, (50, 3))
    write_cloud_table(src, xyz, {})
    bad = tmp_path / "bad.las"
    _patched_header(src, bad, offset, fmt, value)
    assert main(["info", str(bad)]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"m3c2: error: {bad}: ") and words in err, err
    with pytest.raises(CloudReadError, match=words.split(" (")[0]):
        read_cloud(bad)
