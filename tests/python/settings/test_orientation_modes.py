"""--orient origin / barycentre / sensor and away:POINT (section 3.1.2), and CloudCompare's
NormalPreferedOri 6-12 read from params files, each against a synthetic sphere whose normals are
known (radial): the sign rule is CloudCompare's, n . (target - P) >= 0 for "towards"."""
from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest

import m3c2kit
from m3c2kit.cli.main import main
from m3c2kit.base.errors import UsageError
from m3c2kit.io import Cloud, read_cloud, write_cloud_table
from m3c2kit.settings.cloudcompare_params import read_cloudcompare_params
from m3c2kit.settings.orientation import exact_mean

CENTRE = np.array([30.0, -4.0, 2.0])  # the origin lies outside the sphere: "origin" and
RADIUS = 10.0                          # "barycentre" then disagree on the sphere's far side


def sphere(n: int = 40000, radius: float = RADIUS, centre=CENTRE) -> np.ndarray:
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    rho = np.sqrt(1.0 - z * z)
    phi = math.pi * (3.0 - math.sqrt(5.0)) * np.arange(n)
    return centre + radius * np.column_stack([rho * np.cos(phi), rho * np.sin(phi), z])


CLOUD = sphere()
CORE = CLOUD[::97].copy()
OUTWARD = (CORE - CENTRE) / RADIUS


def expected_normals(target, away: bool) -> tuple[np.ndarray, np.ndarray]:
    """The radial normal signed so that n . (target - P) >= 0 (or <= 0 away), and where that
    sign is clear (core points not nearly tangent to the line of sight)."""
    to = np.asarray(target, dtype=float).reshape(-1, 3)[0] - CORE
    dot = np.einsum("ij,ij->i", OUTWARD, to)
    sign = np.where(dot >= 0, 1.0, -1.0) * (-1.0 if away else 1.0)
    clear = np.abs(dot) > 0.05 * np.linalg.norm(to, axis=1)
    return OUTWARD * sign[:, None], clear


def normals_for(orient, **kw) -> np.ndarray:
    out = m3c2kit.normals(CLOUD, CORE, normal_scale=1.0, orient=orient, **kw)
    return np.asarray(out["normal"])


@pytest.mark.parametrize("orient, target, away", [
    ("barycentre", "core_mean", False),
    ("barycenter", "core_mean", False),
    ("away:barycentre", "core_mean", True),
    ("origin", (0.0, 0.0, 0.0), False),
    ("away:origin", (0.0, 0.0, 0.0), True),
    ("away:25,3,40", (25.0, 3.0, 40.0), True),
    ("25,3,40", (25.0, 3.0, 40.0), False),
])
def test_point_modes_orient_as_cloudcompare(orient, target, away):
    if target == "core_mean":
        target = CORE.mean(axis=0)
    want, clear = expected_normals(target, away)
    assert clear.sum() > 0.8 * len(CORE)
    got = normals_for(orient)
    assert np.all(np.einsum("ij,ij->i", got[clear], want[clear]) > 0.99)


def test_origin_and_barycentre_differ_on_this_sphere():
    # Guards the test above: the two targets orient some normals oppositely here.
    a, _ = expected_normals(CORE.mean(axis=0), False)
    b, _ = expected_normals((0.0, 0.0, 0.0), False)
    assert np.sum(np.einsum("ij,ij->i", a, b) < 0) > 0.2 * len(CORE)


def test_barycentre_is_of_the_core_points_not_the_cloud():
    # Core points on one cap: their barycentre is inside the sphere, near the cap, so the cap's
    # normals point inwards; the cloud's barycentre (the centre) would give the same here, but a
    # target beyond the cap's plane could not: check against the core points' mean explicitly.
    cap = CLOUD[(CLOUD[:, 2] - CENTRE[2]) > 0.8 * RADIUS][::5]
    out = m3c2kit.normals(CLOUD, cap, normal_scale=1.0, orient="barycentre")
    to = cap.mean(axis=0) - cap
    assert np.all(np.einsum("ij,ij->i", np.asarray(out["normal"]), to) > 0)


def test_sensor_uses_the_clouds_scan_positions():
    scanner = np.array([[55.0, -4.0, 2.0]])  # outside, on the +x side
    ref = Cloud(CLOUD.copy(), scan_positions=scanner)
    want, clear = expected_normals(scanner, False)
    got = np.asarray(m3c2kit.normals(ref, None, normal_scale=1.0, orient="sensor")["normal"])[::97]
    assert np.all(np.einsum("ij,ij->i", got[clear], want[clear]) > 0.99)
    got = np.asarray(m3c2kit.normals(ref, None, normal_scale=1.0, orient="away:sensor")["normal"])[::97]
    assert np.all(np.einsum("ij,ij->i", got[clear], want[clear]) < -0.99)


def test_sensor_without_scan_positions_is_refused():
    with pytest.raises(UsageError, match="sensor position.*only E57 files carry scanner poses"):
        normals_for("sensor")


def test_distance_sign_follows_the_orientation():
    # Compared = the sphere grown by 0.5: +0.5 along outward normals, -0.5 along inward ones.
    grown = sphere(radius=RADIUS + 0.5)
    common = dict(normal_scale=1.0, projection_scale=1.0, max_depth=2.0)
    out = m3c2kit.compare(CLOUD, grown, CORE, orient="away:barycentre", **common)
    inward = m3c2kit.compare(CLOUD, grown, CORE, orient="barycentre", **common)
    np.testing.assert_allclose(out.distance, 0.5, atol=0.02)
    np.testing.assert_allclose(inward.distance, -0.5, atol=0.02)


def test_away_before_an_axis_is_refused():
    with pytest.raises(UsageError, match="away: goes before a point"):
        normals_for("away:+z")


def test_exact_mean_is_correctly_rounded_and_chunking_free():
    rng = np.random.default_rng(7)
    pts = np.column_stack([rng.uniform(-1, 1, 5001) * 10.0 ** rng.integers(-8, 9, 5001) + 6.3e5,
                           rng.normal(5.1e6, 1e3, 5001), rng.standard_cauchy(5001)])
    whole = exact_mean([pts])
    chunked = exact_mean([pts[i:i + 123] for i in range(0, len(pts), 123)][::-1])
    assert whole.tobytes() == chunked.tobytes()
    exact = [float(sum((Fraction(float(v)) for v in pts[:, a]), Fraction(0)) / len(pts)) for a in range(3)]
    assert whole.tolist() == exact


@pytest.mark.parametrize("ori, orient", [("6", "away:barycentre"), ("7", "barycentre"), ("8", "away:origin"),
                                         ("9", "origin"), ("11", "away:sensor"), ("12", "sensor")])
def test_params_file_point_modes(tmp_path, ori, orient):
    path = tmp_path / "params.txt"
    path.write_text(f"[General]\nM3C2VER=1\nNormalScale=1\nNormalMode=0\nNormalPreferedOri={ori}\n"
                    "SearchScale=1\nSearchDepth=2\n")
    assert read_cloudcompare_params(path)["orient"] == orient


def _write(path, xyz):
    write_cloud_table(path, xyz, {})


def test_params_file_barycentre_end_to_end(tmp_path):
    ref, cmp_ = tmp_path / "ref.ply", tmp_path / "cmp.ply"
    _write(ref, CLOUD)
    _write(cmp_, sphere(radius=RADIUS + 0.5))
    params = tmp_path / "params.txt"
    params.write_text("[General]\nM3C2VER=1\nNormalScale=1\nNormalMode=0\nNormalPreferedOri=6\n"
                      "SearchScale=1\nSearchDepth=2\nSubsampleEnabled=true\nSubsampleRadius=1\n")
    out = tmp_path / "out.csv"
    assert main(["compare", str(ref), str(cmp_), "-o", str(out), "--params", str(params), "-q"]) == 0
    table = read_cloud(out)
    d = table.fields["distance"]
    assert np.nanmedian(d) == pytest.approx(0.5, abs=0.02) and np.nanmin(d) > 0.4
    # The same as the command line's spelling.
    out2 = tmp_path / "out2.csv"
    assert main(["compare", str(ref), str(cmp_), "-o", str(out2), "--params", str(params), "-q",
                 "--orient", "away:barycentre"]) == 0
    assert out.read_bytes() == out2.read_bytes()


def test_params_file_sensor_without_poses_names_file_key_and_option(tmp_path, capsys):
    ref = tmp_path / "ref.ply"
    _write(ref, CLOUD)
    params = tmp_path / "params.txt"
    params.write_text("[General]\nM3C2VER=1\nNormalScale=1\nNormalMode=0\nNormalPreferedOri=12\n"
                      "SearchScale=1\nSearchDepth=2\n")
    assert main(["compare", str(ref), str(ref), "-o", str(tmp_path / "o.csv"), "--params", str(params)]) != 0
    err = capsys.readouterr().err
    assert f"{params}: NormalPreferedOri=12" in err and str(ref) in err and "--orient X,Y,Z" in err
    assert not (tmp_path / "o.csv").exists()


def test_tiled_barycentre_matches_in_memory(tmp_path):
    ref, cmp_ = tmp_path / "ref.ply", tmp_path / "cmp.ply"
    _write(ref, CLOUD)
    _write(cmp_, sphere(radius=RADIUS + 0.5))
    args = ["--normal-scale", "1", "--projection-scale", "1", "--max-depth", "2", "--core-spacing", "1",
            "--orient", "away:barycentre", "-q"]
    mem, tiled = tmp_path / "mem.csv", tmp_path / "tiled.csv"
    assert main(["compare", str(ref), str(cmp_), "-o", str(mem), *args]) == 0
    assert main(["compare", str(ref), str(cmp_), "-o", str(tiled), "--tile-size", "7", *args]) == 0
    a, b = read_cloud(mem), read_cloud(tiled)
    np.testing.assert_array_equal(a.fields["distance"], b.fields["distance"])
    assert np.nanmin(a.fields["distance"]) > 0.4


def test_sensor_from_an_e57_pose(tmp_path):
    pytest.importorskip("pye57")
    scanner = np.array([55.0, -4.0, 2.0])
    path = tmp_path / "scan.e57"
    _e57_sphere(path, scanner)
    out = tmp_path / "n.csv"
    assert main(["normals", str(path), "-o", str(out), "--normal-scale", "1", "--orient", "sensor", "-q"]) == 0
    got = read_cloud(out)
    n = np.column_stack([got.fields["nx"], got.fields["ny"], got.fields["nz"]])
    to = scanner - got.xyz
    facing = np.einsum("ij,ij->i", n, to)
    clear = np.abs(np.einsum("ij,ij->i", (got.xyz - CENTRE) / RADIUS, to)) > 0.05 * np.linalg.norm(to, axis=1)
    assert clear.sum() > 0.5 * len(n) and np.all(facing[clear] > 0)



def _e57_sphere(path, scanner):
    import pye57
    local = CLOUD - scanner
    with pye57.E57(str(path), mode="w") as out:
        out.write_scan_raw({"cartesianX": local[:, 0], "cartesianY": local[:, 1], "cartesianZ": local[:, 2]},
                           name="scan", rotation=np.array([1.0, 0.0, 0.0, 0.0]), translation=scanner)


def test_sensor_with_a_core_file_uses_the_references_pose_when_the_core_file_has_none(tmp_path, capsys):
    pytest.importorskip("pye57")
    scanner = np.array([55.0, -4.0, 2.0])
    ref, core = tmp_path / "scan.e57", tmp_path / "core.ply"
    _e57_sphere(ref, scanner)
    write_cloud_table(core, read_cloud(ref).xyz[::97], {})
    out = tmp_path / "n.csv"
    assert main(["normals", str(ref), "--core", str(core), "-o", str(out), "--normal-scale", "1", "--orient",
                 "away:sensor", "-q"]) == 0
    got = read_cloud(out)
    n = np.column_stack([got.fields["nx"], got.fields["ny"], got.fields["nz"]])
    to = scanner - got.xyz
    clear = np.abs(np.einsum("ij,ij->i", (got.xyz - CENTRE) / RADIUS, to)) > 0.05 * np.linalg.norm(to, axis=1)
    assert clear.sum() > 0.5 * len(n) and np.all(np.einsum("ij,ij->i", n, to)[clear] < 0)
    # Neither file with a pose: both are named.
    plain = tmp_path / "ref.ply"
    write_cloud_table(plain, CLOUD, {})
    assert main(["normals", str(plain), "--core", str(core), "-o", str(tmp_path / "m.csv"), "--normal-scale", "1",
                 "--orient", "sensor"]) != 0
    err = capsys.readouterr().err
    assert f"neither {core} (the core points) nor {plain} has one" in err and "--orient X,Y,Z" in err
