"""docs/errors.md, "Input files" and "Degenerate clouds": missing, unreadable, empty and
mismatched files; clouds of 0, 1 and 2 points; NaN/Inf coordinates; duplicated points;
collinear, coincident and coplanar neighbourhoods; core points far outside the clouds.

Every CLI case checks the exit code, that the message names the file, and that no output file
(nor a temporary one) is left behind."""
from __future__ import annotations

import csv
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from child_env import child_env

import m3c2kit
from m3c2kit.cli.main import main
from m3c2kit.base.errors import CloudReadError, UsageError
from m3c2kit.io import files as io_files
from m3c2kit.engine.result import STATUS_NAMES
from synthetic import grid

BASE = ["--normal-scale", "0.5", "--projection-scale", "0.3", "--max-depth", "0.5"]
STATUS = {name: code for code, name in enumerate(STATUS_NAMES)}


def write_xyz(path: Path, xyz) -> Path:
    with open(path, "w") as f:
        for p in np.atleast_2d(xyz):
            f.write(" ".join(repr(float(c)) for c in p) + "\n")
    return path


def read_csv(path):
    with open(path) as f:
        rows = list(csv.reader(f))
    body = np.array(rows[1:], dtype=float).reshape(-1, len(rows[0]))
    return {name: body[:, k] for k, name in enumerate(rows[0])}


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


def leftovers(directory: Path, stem="out"):
    return sorted(p.name for p in directory.iterdir() if p.name.startswith((stem, f".{stem}")))




# ------------------------------------------------------------------------ missing / unreadable


@pytest.mark.parametrize("role", ["reference", "compared", "core"])
def test_missing_file_exit_1_names_it(pair, capsys, role):
    paths = {"reference": pair / "ref.xyz", "compared": pair / "cmp.xyz", "core": pair / "ref.xyz"}
    paths[role] = pair / "missing.xyz"
    code, _, err = run(capsys, "compare", paths["reference"], paths["compared"], "--core", paths["core"],
                       "-o", pair / "out.csv", *BASE)
    assert code == 1
    assert err == f"m3c2: error: {pair / 'missing.xyz'}: no such file\n"
    assert leftovers(pair) == []


def test_unreadable_file(pair, capsys, monkeypatch):
    def denied(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(io_files, "open", denied, raising=False)
    code, _, err = run(capsys, "compare", pair / "ref.xyz", pair / "cmp.xyz", "-o", pair / "out.csv", *BASE)
    assert code == 1
    assert err == f"m3c2: error: {pair / 'ref.xyz'}: cannot open: Permission denied\n"
    assert leftovers(pair) == []


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads files whatever their mode")
def test_unreadable_file_by_mode(pair, capsys):
    (pair / "ref.xyz").chmod(0)
    code, _, err = run(capsys, "compare", pair / "ref.xyz", pair / "cmp.xyz", "-o", pair / "out.csv", *BASE)
    assert code == 1 and "ref.xyz: cannot open: Permission denied" in err


def test_directory_instead_of_file(pair, capsys):
    (pair / "dir.xyz").mkdir()
    code, _, err = run(capsys, "compare", pair / "dir.xyz", pair / "cmp.xyz", "-o", pair / "out.csv", *BASE)
    assert code == 1 and err == f"m3c2: error: {pair / 'dir.xyz'}: is a directory, not a point-cloud file\n"


def test_fifo_is_refused_without_blocking(pair):
    # Opening a FIFO without a writer blocks forever: it must be refused before it is opened.
    fifo = pair / "pipe.xyz"
    os.mkfifo(fifo)
    proc = subprocess.run([sys.executable, "-m", "m3c2kit", "compare", str(fifo), str(pair / "cmp.xyz"), "-o",
                           str(pair / "out.csv"), *BASE], capture_output=True, text=True, timeout=60,
                          env=child_env())
    assert proc.returncode == 1
    assert proc.stderr.endswith(f"m3c2: error: {fifo}: not a regular file\n")
    assert leftovers(pair) == []


@pytest.mark.parametrize("ext", [".xyz", ".csv", ".las", ".laz", ".ply", ".e57", ".npy"])
def test_empty_file(pair, capsys, ext):
    empty = pair / f"empty{ext}"
    empty.write_bytes(b"")
    code, _, err = run(capsys, "compare", pair / "ref.xyz", empty, "-o", pair / "out.csv", *BASE)
    assert code == 1 and err == f"m3c2: error: {empty}: is empty (0 bytes)\n"
    assert leftovers(pair) == []


@pytest.mark.parametrize("ext, content, message", [
    (".ply", b"LASF" + bytes(400), "the content is LAS/LAZ, not PLY as the extension '.ply' says"),
    (".xyz", b"ply\nformat ascii 1.0\n", "the content is PLY, not ASCII as the extension '.xyz' says"),
    (".las", b"1 2 3\n4 5 6\n", "not a LAS/LAZ file (no 'LASF' signature)"),
    (".laz", b"ply\nformat ascii 1.0\n", "the content is PLY, not LAS/LAZ as the extension '.laz' says"),
    (".e57", b"1 2 3\n4 5 6\n", "not an E57 file (no 'ASTM-E57' signature)"),
    (".npy", b"1 2 3\n", "not a NumPy .npy file (bad magic bytes)"),
    (".csv", b"\x00\x01\x02binary\x00", "binary content; not a text point cloud"),
    (".ply", b"1 2 3\n", "not a PLY file (first line is not 'ply')"),
    (".foo", b"1 2 3\n", "unknown point-cloud file extension '.foo'"),
])
def test_content_not_matching_the_extension(pair, capsys, ext, content, message):
    bad = pair / f"bad{ext}"
    bad.write_bytes(content)
    code, _, err = run(capsys, "compare", bad, pair / "cmp.xyz", "-o", pair / "out.csv", *BASE)
    assert code == 1
    assert err.startswith(f"m3c2: error: {bad}: {message}")
    assert leftovers(pair) == []


# ------------------------------------------------------------------------------ 0, 1, 2 points


def _zero_point_files(directory: Path, shared_data: Path | None) -> dict[str, tuple[Path, str]]:
    header_only = directory / "header.xyz"
    header_only.write_text("x y z\n")
    ply = directory / "none.ply"
    ply.write_bytes(b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
                    b"property float z\nend_header\n")
    files = {"text": (header_only, "no line with three numbers (x y z)"),
             "ply": (ply, "contains no points")}
    if shared_data is not None:
        files["las"] = (shared_data / "readers/pdal/las/no-points.las", "contains no points")
    return files


@pytest.mark.parametrize("role", ["reference", "compared", "core"])
@pytest.mark.parametrize("kind", ["text", "ply", "las"])
def test_zero_points_is_a_clear_error(pair, capsys, shared_data, role, kind):
    path, message = _zero_point_files(pair, shared_data)[kind]
    paths = {"reference": pair / "ref.xyz", "compared": pair / "cmp.xyz", "core": pair / "ref.xyz", role: path}
    code, _, err = run(capsys, "compare", paths["reference"], paths["compared"], "--core", paths["core"],
                       "-o", pair / "out.csv", *BASE)
    assert code == 1
    assert err.startswith(f"m3c2: error: {path}: {message}")
    assert leftovers(pair) == []


@pytest.mark.parametrize("which", ["reference", "compared", "core_points"])
def test_api_zero_points_is_a_usage_error(which):
    clouds = {"reference": grid(), "compared": grid(z=0.1), "core_points": grid()}
    clouds[which] = np.empty((0, 3))
    with pytest.raises(UsageError, match=r"(reference cloud|compared cloud|core_points) is empty"):
        m3c2kit.compare(clouds["reference"], clouds["compared"], clouds["core_points"], normal_scale=0.5,
                     projection_scale=0.3, max_depth=0.5)


@pytest.mark.parametrize("n", [1, 2])
def test_one_or_two_point_reference_runs_and_statuses_explain(pair, capsys, n):
    write_xyz(pair / "few.xyz", grid()[:n])
    code, out, _ = run(capsys, "compare", pair / "few.xyz", pair / "cmp.xyz", "-o", pair / "out.csv", *BASE)
    assert code == 0
    cols = read_csv(pair / "out.csv")
    assert len(cols["distance"]) == n
    assert np.all(cols["status"] == STATUS["too_few_normal_points"])  # a plane needs 3 points
    assert np.isnan(cols["distance"]).all() and np.isnan(cols["lod"]).all()
    assert f"status: too_few_normal_points {n}" in out


@pytest.mark.parametrize("n", [1, 2])
def test_one_or_two_point_compared_cloud(pair, capsys, n):
    # The reference's normals are fine; the compared cloud has one or two points near the corner.
    write_xyz(pair / "few.xyz", grid(z=0.1)[:n])
    code, out, err = run(capsys, "compare", pair / "ref.xyz", pair / "few.xyz", "-o", pair / "out.csv", *BASE)
    assert code == 0
    cols = read_csv(pair / "out.csv")
    status = cols["status"]
    assert set(np.unique(status)) <= {STATUS["empty_cylinder_compared"], STATUS["too_few_points_for_lod"]}
    near = status == STATUS["too_few_points_for_lod"]
    assert near.any()
    assert np.all(cols["n2"][near] <= n) and np.isnan(cols["lod"]).all()
    np.testing.assert_allclose(cols["distance"][near], 0.1, atol=1e-12)
    assert np.isnan(cols["distance"][~near]).all()
    assert "m3c2: warning: " in err  # the cylinders are mostly empty in the compared cloud (warnings: stderr)


@pytest.mark.parametrize("n", [1, 2])
def test_one_or_two_point_clouds_with_vertical_normals(pair, capsys, n):
    write_xyz(pair / "r.xyz", grid()[:n])
    write_xyz(pair / "c.xyz", grid(z=0.1)[:n])
    code, _, _ = run(capsys, "compare", pair / "r.xyz", pair / "c.xyz", "-o", pair / "out.csv",
                     "--normal-source", "vertical", "--projection-scale", "0.3", "--max-depth", "0.5")
    assert code == 0
    cols = read_csv(pair / "out.csv")
    np.testing.assert_allclose(cols["distance"], 0.1, atol=1e-12)  # a distance from 1 point per cloud
    assert np.all(cols["status"] == STATUS["too_few_points_for_lod"]) and np.isnan(cols["lod"]).all()
    assert np.all(cols["significant"] != 1)


def test_two_points_per_cylinder_give_a_lod_with_min_points_2(pair, capsys):
    write_xyz(pair / "r.xyz", [[0, 0, 0], [0.01, 0, 0.002]])
    write_xyz(pair / "c.xyz", [[0, 0, 0.1], [0.01, 0, 0.104]])
    code, _, _ = run(capsys, "compare", pair / "r.xyz", pair / "c.xyz", "-o", pair / "out.csv", "--min-points", "2",
                     "--normal-source", "vertical", "--projection-scale", "0.3", "--max-depth", "0.5")
    assert code == 0
    cols = read_csv(pair / "out.csv")
    assert np.all(cols["status"] == STATUS["ok"]) and np.isfinite(cols["lod"]).all()


def test_one_core_point(pair, capsys):
    write_xyz(pair / "core.xyz", [[1.0, 1.0, 0.0]])
    code, _, _ = run(capsys, "compare", pair / "ref.xyz", pair / "cmp.xyz", "--core", pair / "core.xyz",
                     "-o", pair / "out.csv", *BASE)
    assert code == 0
    cols = read_csv(pair / "out.csv")
    assert cols["status"].tolist() == [STATUS["ok"]]
    np.testing.assert_allclose(cols["distance"], [0.1], atol=1e-12)


# ------------------------------------------------------------------- beyond the index's range


def test_far_outlier_in_a_file_is_refused_naming_it(pair, capsys):
    # D = 0.5: the index's grid cell is 2**-6 (D / 32 rounded down to a power of two), so it keys
    # |coordinates| below 2**40 cells = 2**35 (docs/errors.md).
    far = np.vstack([grid(z=0.1), [[1e12, 0.0, 0.0]]])
    write_xyz(pair / "far.xyz", far)
    code, _, err = run(capsys, "compare", pair / "ref.xyz", pair / "far.xyz", "-o", pair / "out.csv", *BASE)
    assert code == 1
    assert err == (f"m3c2: error: {pair / 'far.xyz'}: a coordinate (1e+12) lies beyond +-3.43597e+10, the range "
                   f"of the spatial index for these scales; remove far outliers or shift the coordinates to a "
                   f"local origin\n")
    assert leftovers(pair) == []


def test_far_outlier_in_an_array_is_a_usage_error():
    from m3c2kit import _core
    from m3c2kit.settings import build_params
    assert _core.max_abs_coordinate(build_params(normal_scale=0.5, projection_scale=0.3, max_depth=0.5)) == 2.0**35
    far = np.vstack([grid(), [[0.0, -2.0**35, 0.0]]])  # exactly at the limit: outside
    with pytest.raises(UsageError, match=r"^the reference cloud: a coordinate \(3\.43597e\+10\) lies beyond"):
        m3c2kit.compare(far, grid(z=0.1), grid(), normal_scale=0.5, projection_scale=0.3, max_depth=0.5)
    # Geocentric-sized coordinates are well inside.
    shifted = grid() + 6.4e6
    r = m3c2kit.compare(shifted, shifted + [0, 0, 0.1], shifted, normal_scale=0.5, projection_scale=0.3, max_depth=0.5)
    assert np.isfinite(r.distance).any()


# --------------------------------------------------------------------------------- NaN / Inf


def test_nonfinite_coordinates_rejected_with_a_count(pair, capsys):
    bad = grid()
    bad[[3, 50, 70], 2] = np.nan
    bad[[5, 9], 0] = [np.inf, -np.inf]
    write_xyz(pair / "bad.xyz", bad)
    code, _, err = run(capsys, "compare", pair / "bad.xyz", pair / "cmp.xyz", "-o", pair / "out.csv", *BASE)
    assert code == 1
    assert err == (f"m3c2: error: {pair / 'bad.xyz'}: 5 of 400 points have non-finite (NaN or infinite) "
                   f"coordinates; use --drop-nonfinite to drop them\n")
    assert leftovers(pair) == []


@pytest.mark.parametrize("role", ["compared", "core"])
def test_nonfinite_coordinates_in_compared_and_core(pair, capsys, role):
    bad = grid()
    bad[0] = np.nan
    write_xyz(pair / "bad.xyz", bad)
    paths = {"compared": pair / "cmp.xyz", "core": pair / "ref.xyz", role: pair / "bad.xyz"}
    code, _, err = run(capsys, "compare", pair / "ref.xyz", paths["compared"], "--core", paths["core"],
                       "-o", pair / "out.csv", *BASE)
    assert code == 1 and "bad.xyz: 1 of 400 points have non-finite" in err


def test_drop_nonfinite_runs_and_reports_the_drop(pair, capsys):
    bad = grid()
    bad[[3, 50]] = np.nan
    write_xyz(pair / "bad.xyz", bad)
    code, out, err = run(capsys, "compare", pair / "bad.xyz", pair / "cmp.xyz", "-o", pair / "out.csv",
                       "--drop-nonfinite", *BASE)
    assert code == 0
    assert len(read_csv(pair / "out.csv")["distance"]) == 398
    assert f"m3c2: note: dropped 2 points with non-finite coordinates from {pair / 'bad.xyz'}" in err


@pytest.mark.parametrize("drop", [["--drop-nonfinite"], []])
def test_all_nonfinite_is_an_error_with_or_without_drop(pair, capsys, drop):
    """Without --drop-nonfinite the message advised it, which would have dropped every point
    (hostile round 2): a file with no finite point says so, whichever the option."""
    write_xyz(pair / "nan.xyz", np.full((4, 3), np.nan))
    code, _, err = run(capsys, "compare", pair / "nan.xyz", pair / "cmp.xyz", "-o", pair / "out.csv", *drop, *BASE)
    assert code == 1
    assert err == f"m3c2: error: {pair / 'nan.xyz'}: contains no points with finite coordinates (4 non-finite)\n"


@pytest.mark.parametrize("which, name", [(0, "reference cloud"), (1, "compared cloud"), (2, "core points")])
def test_api_nonfinite_arrays_are_usage_errors(which, name):
    arrays = [grid(), grid(z=0.1), grid()]
    arrays[which] = arrays[which].copy()
    arrays[which][7, 1] = np.inf
    with pytest.raises(UsageError, match=rf"^{name} has 1 non-finite coordinates \(NaN or Inf\)$"):
        m3c2kit.compare(*arrays, normal_scale=0.5, projection_scale=0.3, max_depth=0.5)


# ------------------------------------------------------------------------ duplicates, geometry


def _noisy(n=30, z=0.0, seed=0):
    rng = np.random.default_rng(seed)
    g = grid(n, 0.05, z)
    g[:, 2] += rng.normal(0, 0.002, len(g))
    return g


def test_duplicated_points_count_twice_and_keep_the_distance():
    ref, cmp = _noisy(), _noisy(z=0.1, seed=1)
    core = ref[::37]
    kw = dict(normal_scale=0.5, projection_scale=0.3, max_depth=0.5)
    once = m3c2kit.compare(ref, cmp, core, **kw)
    twice = m3c2kit.compare(np.repeat(ref, 2, axis=0), np.repeat(cmp, 2, axis=0), core, **kw)
    np.testing.assert_array_equal(twice.n1, 2 * once.n1)
    np.testing.assert_array_equal(twice.n2, 2 * once.n2)
    np.testing.assert_allclose(twice.distance, once.distance, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(twice.status, once.status)
    assert np.all(twice.lod < once.lod)  # duplicates shrink the standard error (documented caveat)


def test_compared_identical_to_reference_gives_zero_and_nothing_significant():
    ref = _noisy()
    r = m3c2kit.compare(ref, ref.copy(), ref[::41], normal_scale=0.5, projection_scale=0.3, max_depth=0.5)
    assert np.all(r.distance == 0.0) and not r.significant.any() and np.all(r.lod > 0)


def test_coincident_points_give_degenerate_normal():
    ref = np.repeat([[1.0, 1.0, 0.0]], 50, axis=0)
    r = m3c2kit.compare(ref, ref + [0, 0, 0.1], ref[:1], normal_scale=0.5, projection_scale=0.3, max_depth=0.5)
    assert r.status.tolist() == [STATUS["degenerate_normal"]]
    assert np.isnan(r.distance).all() and np.isnan(r.normal).all()


@pytest.mark.parametrize("direction", [(1, 0, 0), (1, 1, 0), (0.3, -0.2, 0.9)])
def test_collinear_neighbourhood_gives_degenerate_normal(direction):
    t = np.linspace(-1, 1, 81)[:, None]
    line = t * np.asarray(direction, dtype=float)
    r = m3c2kit.compare(line, line + [0, 0, 0.1], line[40:41], normal_scale=0.5, projection_scale=0.3, max_depth=0.5)
    assert r.status.tolist() == [STATUS["degenerate_normal"]]
    assert np.isnan(r.distance).all()


def test_coplanar_neighbourhood_is_a_valid_normal():
    # Coplanar (not collinear) points are the ideal plane fit: a normal, roughness 0, status ok.
    ref, cmp = grid(), grid(z=0.1)
    r = m3c2kit.compare(ref, cmp, ref[[210]], normal_scale=0.5, projection_scale=0.3, max_depth=0.5)
    assert r.status.tolist() == [STATUS["ok"]]
    np.testing.assert_allclose(np.abs(r.normal[0]), [0.0, 0.0, 1.0], rtol=0, atol=1e-15)
    assert r.roughness[0] < 1e-15  # 0 up to rounding


def test_collinear_cloud_through_the_cli(tmp_path, capsys):
    t = np.linspace(0, 2, 101)[:, None]
    write_xyz(tmp_path / "line.xyz", t * [1.0, 0.0, 0.0])
    write_xyz(tmp_path / "cmp.xyz", grid(z=0.1))
    code, out, _ = run(capsys, "compare", tmp_path / "line.xyz", tmp_path / "cmp.xyz", "-o", tmp_path / "out.csv",
                       *BASE)
    assert code == 0
    assert np.all(read_csv(tmp_path / "out.csv")["status"] == STATUS["degenerate_normal"])
    assert "status: degenerate_normal 101" in out


# ------------------------------------------------------------------------- far core points


@pytest.mark.parametrize("far", [1e6, 1e150, -1e300])
def test_core_points_far_outside_get_statuses_not_a_crash(pair, capsys, far):
    write_xyz(pair / "core.xyz", [[far, far, 0.0], [1.0, 1.0, 0.0], [0.5, 0.5, far]])
    code, _, _ = run(capsys, "compare", pair / "ref.xyz", pair / "cmp.xyz", "--core", pair / "core.xyz",
                     "-o", pair / "out.csv", *BASE)
    assert code == 0
    cols = read_csv(pair / "out.csv")
    assert cols["status"].tolist() == [STATUS["too_few_normal_points"], STATUS["ok"], STATUS["too_few_normal_points"]]
    code, _, _ = run(capsys, "compare", pair / "ref.xyz", pair / "cmp.xyz", "--core", pair / "core.xyz",
                     "-o", pair / "out.csv", "--normal-source", "vertical", "--projection-scale", "0.3",
                     "--max-depth", "0.5")
    assert code == 0
    cols = read_csv(pair / "out.csv")
    assert cols["status"].tolist() == [STATUS["empty_cylinder_reference"], STATUS["ok"],
                                       STATUS["empty_cylinder_reference"]]
    assert np.isnan(cols["distance"][[0, 2]]).all()


@pytest.mark.parametrize("option", ["--core-spacing", "--normal-subsample"])
def test_spacing_between_the_engine_and_the_old_python_limits_is_refused(tmp_path, capsys, option):
    # extent / spacing = 1e13: above the engine's 2**40 cells, below the 2**62 Python used to
    # check, so the engine's ValueError escaped as a traceback (issue 12). One rule now, the engine's.
    write_xyz(tmp_path / "ref.xyz", np.vstack([grid(), [[1e12, 0.0, 0.0]]]))
    write_xyz(tmp_path / "cmp.xyz", grid(z=0.1))
    code, _, err = run(capsys, "compare", tmp_path / "ref.xyz", tmp_path / "cmp.xyz", "-o", tmp_path / "out.csv",
                       option, "0.1", *BASE)
    assert code == 2
    assert err.startswith(f"m3c2: error: {option} 0.1 is too small for clouds spanning 1e+12 on an axis")
    code, _, err = run(capsys, "subsample", tmp_path / "ref.xyz", "-o", tmp_path / "out.csv", "--spacing", "0.1")
    assert code == 2 and err.startswith("m3c2: error: --spacing 0.1 is too small")
    with pytest.raises(m3c2kit.UsageError, match="--spacing"):
        m3c2kit.subsample(np.array([[0.0, 0, 0], [1e12, 0, 0]]), 0.1)


def test_read_cloud_error_types_are_documented(tmp_path):
    with pytest.raises(CloudReadError):
        m3c2kit.read(tmp_path / "nothing.las")


@pytest.mark.parametrize("option", ["--core-spacing", "--normal-subsample"])
def test_spacing_too_small_for_the_extent_is_refused(tmp_path, capsys, option):
    # The engine's subsampling grid index is a 64-bit integer per axis: a far outlier (or a tiny
    # spacing) would overflow it (undefined behaviour found by UBSan), so the API refuses first.
    write_xyz(tmp_path / "ref.xyz", np.vstack([grid(), [[1e300, 0.0, 0.0]]]))
    write_xyz(tmp_path / "cmp.xyz", grid(z=0.1))
    code, _, err = run(capsys, "compare", tmp_path / "ref.xyz", tmp_path / "cmp.xyz", "-o", tmp_path / "out.csv",
                       option, "0.1", *BASE)
    assert code == 2
    assert err == (f"m3c2: error: {option} 0.1 is too small for clouds spanning 1e+300 on an axis (at most 2**40 "
                   f"spacings); remove far outliers or use a larger spacing\n")
    code, _, err = run(capsys, "subsample", tmp_path / "ref.xyz", "-o", tmp_path / "out.csv", "--spacing", "0.1")
    assert code == 2 and "--spacing 0.1 is too small" in err
