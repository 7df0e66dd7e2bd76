"""docs/errors.md, "Corrupt and truncated files": through the command line, as a subprocess with
a timeout (a hang fails the test), every broken LAS/LAZ/E57/PLY/ASCII file exits 1 with a
message naming the file and leaves no output file."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pye57
import pytest

from child_env import child_env
from m3c2kit.io import write_cloud_table

BASE = ["--normal-scale", "0.5", "--projection-scale", "0.3", "--max-depth", "0.5", "--quiet"]
TIMEOUT = 120  # seconds; a correct rejection takes well under one

# Shared files that must be rejected, with a phrase of the message.
SHARED_BROKEN = {
    "laszip-broken/broken_coder.laz": "unknown LASzip coder",
    "laszip-broken/broken_compressor.laz": "unknown LASzip compressor",
    "laszip-broken/broken_size.laz": "point-wise",
    "laszip-broken/broken_type.laz": "point-wise",
    "laszip-broken/broken_version.laz": "point-wise",
    "pdal/las/bad_vlr_count.las": "malformed LAS header",
    "pdal/las/garbage_nVariableLength.las": "malformed LAS header",
    "pdal/las/1.2-with-color-clipped.las": "truncated",
    "pdal/las/permutations/1.2-no-points.las": "truncated",
    "pdal/ply/no_vertex.ply": "no 'vertex' element",
    "pdal/ply/sized_dims.ply": "no 'z' property",
    "pdal/text/badheader.txt": "ambiguously",
    "e57/libE57Format/self/bad-crc.e57": "checksum mismatch",
}




def cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "m3c2kit", *map(str, args)], capture_output=True, text=True,
                          timeout=TIMEOUT, env=child_env(), cwd=cwd)


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    d = tmp_path_factory.mktemp("good")
    g = np.stack(np.meshgrid(np.arange(20) * 0.1, np.arange(20) * 0.1), -1).reshape(-1, 2)
    np.savetxt(d / "cmp.xyz", np.column_stack([g, np.full(len(g), 0.1)]))
    return d


def _assert_rejected(proc, path: Path, phrase: str, out_dir: Path):
    assert proc.returncode == 1, proc.stderr
    last = proc.stderr.strip().splitlines()[-1]
    assert last.startswith(f"m3c2: error: {path}: "), proc.stderr
    assert phrase in last, last
    assert "Traceback" not in proc.stderr
    assert not [p for p in out_dir.iterdir() if p.name.startswith(("out", ".out"))]


@pytest.mark.slow
@pytest.mark.parametrize("rel", sorted(SHARED_BROKEN))
def test_shared_broken_files_through_the_cli(shared_data, good, tmp_path, rel):
    path = shared_data / "readers" / rel
    proc = cli("compare", path, good / "cmp.xyz", "-o", tmp_path / "out.laz", *BASE)
    _assert_rejected(proc, path, SHARED_BROKEN[rel], tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("role", ["compared", "core"])
def test_broken_file_as_compared_or_core(shared_data, good, tmp_path, role):
    broken = shared_data / "readers/laszip-broken/broken_coder.laz"
    files = {"compared": good / "cmp.xyz", "core": good / "cmp.xyz", role: broken}
    proc = cli("compare", good / "cmp.xyz", files["compared"], "--core", files["core"], "-o", tmp_path / "out.csv",
               *BASE)
    _assert_rejected(proc, broken, "unknown LASzip coder", tmp_path)


def _copies(source_dir: Path, shared_data: Path) -> dict[str, tuple[Path, str]]:
    """Truncated and damaged copies of valid files, name -> (path, phrase of the message)."""
    made: dict[str, tuple[Path, str]] = {}

    def cut(name: str, data: bytes, fraction: float, phrase: str, suffix: str):
        path = source_dir / f"{name}{suffix}"
        path.write_bytes(data[: int(len(data) * fraction)])
        made[path.name] = (path, phrase)

    las = (shared_data / "readers/laspy/simple.las").read_bytes()
    laz = (shared_data / "readers/laspy/simple.laz").read_bytes()
    cut("las_half", las, 0.5, "truncated", ".las")
    cut("las_header_cut", las, 100 / len(las), "truncated LAS header", ".las")
    cut("las_in_vlrs", las, 240 / len(las), "truncated", ".las")
    cut("laz_half", laz, 0.5, "IoError", ".laz")  # lazrs: "failed to fill whole buffer"
    cut("laz_90", laz, 0.9, "IoError", ".laz")
    cut("laz_header_cut", laz, 50 / len(laz), "truncated LAS header", ".laz")
    flipped = bytearray(laz)
    for k in range(len(laz) // 2, len(laz) - 64, 97):  # damage the compressed points
        flipped[k] ^= 0x5A
    (source_dir / "laz_flipped.laz").write_bytes(bytes(flipped))
    made["laz_flipped.laz"] = (source_dir / "laz_flipped.laz", "")  # whatever lazrs says, it is an error

    rng = np.random.default_rng(0)
    xyz = rng.uniform(0, 10, (2000, 3))
    e57 = source_dir / "full.e57"
    with pye57.E57(str(e57), mode="w") as out:
        out.write_scan_raw({"cartesianX": xyz[:, 0], "cartesianY": xyz[:, 1], "cartesianZ": xyz[:, 2]})
    data = e57.read_bytes()
    e57.unlink()
    cut("e57_half", data, 0.5, "ErrorBadFileLength", ".e57")
    cut("e57_header_cut", data, 20 / len(data), "", ".e57")  # libE57Format: "inconsistent internal state"

    ply = source_dir / "full.ply"
    write_cloud_table(ply, xyz, {"intensity": np.arange(2000, dtype=np.uint16)})
    data = ply.read_bytes()
    ply.unlink()
    cut("ply_body_cut", data, 0.6, "truncated: PLY header declares 2000 vertices", ".ply")
    cut("ply_header_cut", data, 60 / len(data), "truncated PLY header", ".ply")
    text_ply = b"ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n" \
               b"end_header\n0 0 0\n1 0 0\n0 1 0\n"
    (source_dir / "ply_ascii_short.ply").write_bytes(text_ply)
    made["ply_ascii_short.ply"] = (source_dir / "ply_ascii_short.ply", "truncated: PLY header declares 4 vertices")

    text = "".join(f"{x!r} {y!r} {z!r}\n" for x, y, z in xyz[:50].tolist()).encode()
    cut_mid_line = text[: text.rindex(b" ")]  # the last line loses its z
    (source_dir / "text_cut.xyz").write_bytes(cut_mid_line)
    made["text_cut.xyz"] = (source_dir / "text_cut.xyz", "line 50 has only 2 values, fewer than x, y, z (truncated file?)")
    (source_dir / "text_garbage.csv").write_bytes(b"x,y,z\n1,2,3\n4,5,6\n7,8,\xff\xfe\n")
    made["text_garbage.csv"] = (source_dir / "text_garbage.csv", "header column 2 ('z') does not hold numbers")
    return made


@pytest.fixture(scope="module")
def damaged(tmp_path_factory, shared_data):
    return _copies(tmp_path_factory.mktemp("damaged"), shared_data)


DAMAGED_NAMES = ["las_half.las", "las_header_cut.las", "las_in_vlrs.las", "laz_half.laz", "laz_90.laz",
                 "laz_header_cut.laz", "laz_flipped.laz", "e57_half.e57", "e57_header_cut.e57", "ply_body_cut.ply",
                 "ply_header_cut.ply", "ply_ascii_short.ply", "text_cut.xyz", "text_garbage.csv"]


@pytest.mark.slow
@pytest.mark.parametrize("name", DAMAGED_NAMES)
def test_truncated_and_damaged_copies_through_the_cli(damaged, good, tmp_path, name):
    path, phrase = damaged[name]
    proc = cli("compare", path, good / "cmp.xyz", "-o", tmp_path / "out.laz", *BASE)
    _assert_rejected(proc, path, phrase, tmp_path)


def test_every_damaged_copy_is_listed(damaged):
    assert sorted(damaged) == sorted(DAMAGED_NAMES)
