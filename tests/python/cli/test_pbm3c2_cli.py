"""`m3c2 pbm3c2 REF CMP -o OUT` end to end (docs/cli.md): LAS epochs with a segment_id field written
to tmp_path, outputs in every table format with the documented columns, --per-point, --segments,
the random forest from a --training CSV; and the caller's mistakes: exit code 2, a message naming
the file, and no output (nor a temporary one) left behind."""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from m3c2kit.base.errors import QuantisationWarning
from m3c2kit.cli.main import main
from m3c2kit.io import read_cloud, write_cloud_table

#: The pairs' columns after x, y, z (docs/cli.md; m3c2kit.pbm3c2's pairs).
COLUMNS = ["nx", "ny", "nz", "distance", "lod", "significant", "n1", "n2", "reference_segment", "compared_segment",
           "roughness1", "roughness2", "normal_angle", "status", "plane_misfit"]
PER_POINT = ["segment", "distance", "lod", "significant", "status"]
#: Four facets 1.2 m square, 2.5 m apart, tilted up to 20 deg from the vertical, 3 mm noise; ids 7, 17, 27, 37.
MOVES = np.array([0.0, 0.03, -0.06, 0.01])
IDS = 7 + 10 * np.arange(len(MOVES))
SEGMENTS = ["--segments", "segment_id"]


def _epochs(seed=3):
    rng = np.random.default_rng(seed)
    out = {"ref": ([], []), "cmp": ([], [])}
    for k, move in enumerate(MOVES):
        tilt, azimuth = math.radians(rng.uniform(0, 20)), rng.uniform(0, 2 * math.pi)
        n = np.array([math.sin(tilt) * math.cos(azimuth), math.sin(tilt) * math.sin(azimuth), math.cos(tilt)])
        a = np.cross([1.0, 0.0, 0.0], n)
        a /= np.linalg.norm(a)
        b = np.cross(n, a)
        for name, shift in (("ref", 0.0), ("cmp", move)):
            u, v = rng.uniform(-0.6, 0.6, (2, 500))
            height = shift + rng.normal(0, 0.003, 500)
            xyz = [2.5 * k, 0.0, 0.0] + height[:, None] * n + u[:, None] * a + v[:, None] * b
            out[name][0].append(xyz)
            out[name][1].append(np.full(500, IDS[k]))
    return {name: (np.vstack(xyz), np.concatenate(ids)) for name, (xyz, ids) in out.items()}


@pytest.fixture(scope="module")
def epochs(tmp_path_factory):
    """ref.las and cmp.las with a segment_id field; also ref.ply without it."""
    folder = tmp_path_factory.mktemp("pbm3c2")
    clouds = _epochs()
    with warnings.catch_warnings():  # LAS's scale moves the coordinates by 5e-9 m: nothing here
        warnings.simplefilter("ignore", QuantisationWarning)
        for name, (xyz, ids) in clouds.items():
            write_cloud_table(folder / f"{name}.las", xyz, {"segment_id": ids})
    write_cloud_table(folder / "plain.ply", clouds["cmp"][0], {})
    return folder


def run(capsys, *argv):
    code = main(["pbm3c2", *[str(a) for a in argv]])
    out = capsys.readouterr()
    return code, out.out, out.err


def leftovers(directory, stem="out"):
    return sorted(p.name for p in directory.iterdir() if p.name.startswith((stem, f".{stem}")))


@pytest.mark.parametrize("ext", ["csv", "las", "ply", "txt"])
def test_outputs_have_the_documented_columns(epochs, tmp_path, capsys, ext):
    out = tmp_path / f"out.{ext}"
    code, said, _ = run(capsys, epochs / "ref.las", epochs / "cmp.las", "-o", out, *SEGMENTS)
    assert code == 0
    assert "4 segments" in said and "4 of 4 reference segments paired" in said and f"wrote {out}" in said
    table = read_cloud(out)
    assert [c for c in table.fields if c in COLUMNS] == COLUMNS
    if ext in ("csv", "txt"):  # text: exactly the columns, in their order
        assert list(table.fields) == COLUMNS
    np.testing.assert_array_equal(table.fields["reference_segment"], IDS)
    np.testing.assert_array_equal(table.fields["compared_segment"], IDS)
    np.testing.assert_array_equal(table.fields["status"], 0)
    np.testing.assert_allclose(table.fields["distance"], MOVES, atol=1.5e-3)
    np.testing.assert_array_equal(table.fields["significant"], MOVES != 0)
    ref = _epochs()["ref"]
    for k, i in enumerate(IDS):  # x, y, z: the reference segment's centroid (LAS: at its scale)
        np.testing.assert_allclose(table.xyz[k], ref[0][ref[1] == i].mean(axis=0), atol=1e-6)


def test_text_header_names_every_column(epochs, tmp_path, capsys):
    out = tmp_path / "out.csv"
    assert run(capsys, epochs / "ref.las", epochs / "cmp.las", "-o", out, *SEGMENTS, "--quiet")[0] == 0
    assert out.read_text().splitlines()[0] == ",".join(["x", "y", "z", *COLUMNS])


def test_per_point(epochs, tmp_path, capsys):
    out, points = tmp_path / "out.csv", tmp_path / "points.txt"
    code, said, _ = run(capsys, epochs / "ref.las", epochs / "cmp.las", "-o", out, "--per-point", points, *SEGMENTS)
    assert code == 0 and f"wrote {out} and {points}" in said
    pp, pairs = read_cloud(points), read_cloud(out)
    assert list(pp.fields) == PER_POINT
    ref_xyz, ref_ids = _epochs()["ref"]
    assert len(pp.xyz) == len(ref_xyz)
    np.testing.assert_array_equal(pp.fields["segment"], ref_ids)
    row = {int(s): k for k, s in enumerate(pairs.fields["reference_segment"])}
    rows = np.array([row[int(s)] for s in ref_ids])
    for name in PER_POINT[1:]:
        np.testing.assert_array_equal(pp.fields[name], pairs.fields[name][rows], err_msg=name)


def test_grown_segments_without_the_field(epochs, tmp_path, capsys):
    """No --segments: both clouds are segmented (D given: no suggestion run), the same facets found."""
    out = tmp_path / "out.csv"
    code, said, _ = run(capsys, epochs / "ref.las", epochs / "cmp.las", "-o", out, "--normal-scale", "0.25")
    assert code == 0 and "region growing, D 0.25" in said
    table = read_cloud(out)
    assert len(table.xyz) == 4 and (table.fields["status"] == 0).all()
    order = np.argsort(table.xyz[:, 0])  # the facets lie along x
    np.testing.assert_allclose(table.fields["distance"][order], MOVES, atol=1.5e-3)


def _forest_run(epochs, tmp_path, capsys):
    pytest.importorskip("sklearn")
    training = tmp_path / "training.csv"
    lines = ["reference,compared,label"] + [f"{i},{i},1" for i in IDS] + \
        [f"{IDS[k]},{IDS[k + 1]},0" for k in range(3)] + [f"{IDS[k + 1]},{IDS[k]},0" for k in range(3)]
    training.write_text("\n".join(lines) + "\n")
    out = tmp_path / "out.csv"
    code, said, _ = run(capsys, epochs / "ref.las", epochs / "cmp.las", "-o", out, *SEGMENTS,
                        "--correspondence", "forest", "--training", training, "--search-radius", "3")
    assert code == 0 and "(forest, search radius 3)" in said
    return read_cloud(out)


def test_forest_with_a_training_csv_with_header(epochs, tmp_path, capsys):
    table = _forest_run(epochs, tmp_path, capsys)
    assert sorted(table.fields) == sorted(COLUMNS + ["probability"])
    np.testing.assert_array_equal(table.fields["compared_segment"], IDS)
    assert (table.fields["probability"] >= 0.5).all()


def test_forest_columns_in_the_documented_order(epochs, tmp_path, capsys):
    """docs/pbm3c2.md's table and PBM3C2Result's docstring: ..., status, plane_misfit, probability."""
    assert list(_forest_run(epochs, tmp_path, capsys).fields) == COLUMNS + ["probability"]


@pytest.mark.parametrize("case", ["missing field", "missing field in compared", "bad csv line", "csv of 2 columns",
                                  "output is input", "per-point is input", "training without forest",
                                  "mutual with forest", "forest without training", "normal scale with segments"])
def test_errors_exit_2_name_the_file_and_leave_nothing(epochs, tmp_path, capsys, case):
    training = tmp_path / "pairs.csv"
    training.write_text("7,7,1\n7,17,0\n17,x,1\n" if case == "bad csv line" else
                        "7,7\n" if case == "csv of 2 columns" else "7,7,1\n7,17,0\n")
    ref, cmp_, out = epochs / "ref.las", epochs / "cmp.las", tmp_path / "out.csv"
    argv, message = {
        "missing field": ([ref, cmp_, "-o", out, "--segments", "plane"], f"{ref}: no field 'plane' (--segments)"),
        "missing field in compared": ([ref, epochs / "plain.ply", "-o", out, *SEGMENTS],
                                      f"{epochs / 'plain.ply'}: no field 'segment_id'"),
        "bad csv line": ([ref, cmp_, "-o", out, *SEGMENTS, "--correspondence", "forest", "--training", training],
                         f"{training}, line 3: expected 'reference id, compared id, 1 or 0', got '17,x,1'"),
        "csv of 2 columns": ([ref, cmp_, "-o", out, *SEGMENTS, "--correspondence", "forest", "--training", training],
                             f"{training}, line 1: expected 3 columns"),
        "output is input": ([ref, cmp_, "-o", cmp_, *SEGMENTS], f"-o '{cmp_}' is the compared cloud"),
        "per-point is input": ([ref, cmp_, "-o", out, "--per-point", ref, *SEGMENTS],
                               f"--per-point '{ref}' is the reference cloud"),
        "training without forest": ([ref, cmp_, "-o", out, *SEGMENTS, "--training", training],
                                    "--training would change nothing in this run"),
        "mutual with forest": ([ref, cmp_, "-o", out, *SEGMENTS, "--correspondence", "forest", "--training", training,
                                "--mutual"], f"{cmp_} against {ref}: --mutual would change nothing"),
        "forest without training": ([ref, cmp_, "-o", out, *SEGMENTS, "--correspondence", "forest"],
                                    "give --training CSV"),
        "normal scale with segments": ([ref, cmp_, "-o", out, *SEGMENTS, "--normal-scale", "0.3"],
                                       "--normal-scale would change nothing"),
    }[case]
    before = {p.name: p.stat().st_mtime_ns for p in epochs.iterdir()}
    code, said, err = run(capsys, *argv, "--per-point", tmp_path / "out_points.csv") if "per-point" not in case \
        else run(capsys, *argv)
    assert code == 2, err
    assert err.startswith("m3c2: error: ") and message in err, err
    assert said == ""
    assert leftovers(tmp_path) == []
    assert {p.name: p.stat().st_mtime_ns for p in epochs.iterdir()} == before  # the inputs untouched
