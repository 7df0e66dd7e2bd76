"""docs/errors.md, "Output": a full disk (or a file size limit) while a tiled run writes its
spill files, while `--report` writes the HTML report, and while `--grid` writes its GeoTIFF
rasters (issue 15). Each exits 1 with one line naming the user's file or folder (never a
temporary) and the problem, no traceback, no partial output, no leftover, older files intact.

A real full disk is a small tmpfs mounted by the test (root in a container that allows mount;
skipped with the reason elsewhere); the variants that always run limit the file size
(RLIMIT_FSIZE in a child: EFBIG, "File too large") or make the lowest write primitive fail."""
from __future__ import annotations

import errno
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from child_env import child_env

from m3c2kit.cli.main import main

SPILL_MESSAGE = "cannot write the tiled run's spill files (kept in a work folder there until the run ends)"
OLDER = b"older output\n"


def _cloud(n: int, z: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, 20, (n, 2))
    return np.column_stack([xy, z + rng.normal(0, 0.01, n)])


@pytest.fixture
def clouds(tmp_path):
    """20,000-point clouds: one tile's core spill alone is 480 KB."""
    d = tmp_path / "in"
    d.mkdir()
    np.save(d / "ref.npy", _cloud(20_000, 0.0, 1))
    np.save(d / "cmp.npy", _cloud(20_000, 0.05, 2))
    return d


@pytest.fixture
def grid_pair(tmp_path):
    """400 points on a 0.1 grid with noise, 0.1 apart (a few kB of table, a 250 kB report)."""
    d = tmp_path / "in"
    d.mkdir(exist_ok=True)
    g = np.stack(np.meshgrid(np.arange(20) * 0.1, np.arange(20) * 0.1), -1).reshape(-1, 2)
    rng = np.random.default_rng(1)
    for name, z in (("ref", 0.0), ("cmp", 0.1)):
        np.savetxt(d / f"{name}.xyz", np.column_stack([g, z + rng.normal(0, 0.01, len(g))]), fmt="%.17g")
    return d


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


def errors(err: str) -> list[str]:
    assert "Traceback" not in err, err
    return [line for line in err.splitlines() if line.startswith("m3c2: error:")]


def leftovers(folder: Path, keep=()) -> list[str]:
    return sorted(name for name in os.listdir(folder) if name not in keep)


_FSIZE_CHILD = textwrap.dedent("""
    import resource, signal, sys
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit then fails with EFBIG
    limit = int(sys.argv[1])
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    from m3c2kit.cli.main import main
    sys.exit(main(sys.argv[2:]))
""")


def run_with_file_size_limit(limit: int, *argv) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", _FSIZE_CHILD, str(limit), *map(str, argv)], capture_output=True,
                          text=True, timeout=300, env=child_env())


TILED = ["--normal-scale", "1", "--projection-scale", "1", "--max-depth", "1", "--tile-size", "100", "--quiet"]


# ------------------------------------------------------------------------- tiled run's spills

def test_full_disk_while_a_tiled_run_spills(clouds, small_disk, capsys):
    disk = small_disk("256k")
    out = disk / "out.csv"
    out.write_bytes(OLDER)
    code, _, err = run(capsys, "compare", clouds / "ref.npy", clouds / "cmp.npy", "-o", out, *TILED)
    assert code == 1
    assert errors(err) == [f"m3c2: error: {disk}: {SPILL_MESSAGE}: No space left on device"]
    assert out.read_bytes() == OLDER
    assert leftovers(disk, keep={"out.csv"}) == []  # no spill folder, no temporary


def test_file_size_limit_while_a_tiled_run_spills(clouds, tmp_path):
    folder = tmp_path / "outdir"
    folder.mkdir()
    out = folder / "out.csv"
    out.write_bytes(OLDER)
    proc = run_with_file_size_limit(128 * 1024, "compare", clouds / "ref.npy", clouds / "cmp.npy", "-o", out,
                                    *TILED)
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr == f"m3c2: error: {folder}: {SPILL_MESSAGE}: File too large\n"
    assert out.read_bytes() == OLDER
    assert leftovers(folder, keep={"out.csv"}) == []


# --------------------------------------------------------------------------------- --report

REPORT = ["--normal-scale", "0.5", "--projection-scale", "0.3", "--max-depth", "0.5", "--quiet"]


@pytest.mark.slow
def test_full_disk_while_writing_the_report_names_it(grid_pair, small_disk, capsys):
    disk = small_disk("128k")  # the table (about 40 kB) fits, the report (about 250 kB) does not
    out, html = disk / "out.csv", disk / "report.html"
    html.write_bytes(OLDER)
    code, _, err = run(capsys, "compare", grid_pair / "ref.xyz", grid_pair / "cmp.xyz", "-o", out,
                       "--report", html, *REPORT)
    assert code == 1
    assert errors(err) == [f"m3c2: error: {html}: No space left on device"]
    assert html.read_bytes() == OLDER and not out.exists()
    assert leftovers(disk, keep={"report.html"}) == []


@pytest.mark.slow
def test_file_size_limit_while_writing_the_report_names_it(grid_pair, tmp_path):
    folder = tmp_path / "outdir"
    folder.mkdir()
    out, html = folder / "out.csv", folder / "report.html"
    html.write_bytes(OLDER)
    proc = run_with_file_size_limit(128 * 1024, "compare", grid_pair / "ref.xyz", grid_pair / "cmp.xyz", "-o", out,
                                    "--report", html, *REPORT)
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr == f"m3c2: error: {html}: File too large\n"
    assert html.read_bytes() == OLDER and not out.exists()
    assert leftovers(folder, keep={"report.html"}) == []


# ------------------------------------------------------------------------------------ --grid

GRID = ["--grid", "0.1", "--max-depth", "0.5", "--quiet"]


def test_full_disk_while_writing_the_rasters_names_the_raster(grid_pair, small_disk, capsys):
    # Before: GDAL dropped the write errors raised while it closed each file: exit 0 and 0-byte
    # rasters; or the message named the temporary.
    disk = small_disk("8k")  # the 5 kB LAZ table fits (2 pages), the first raster does not
    out = disk / "g.laz"  # every column (--all-fields): the default LAS table is smaller than 5 kB
    code, _, err = run(capsys, "compare", grid_pair / "ref.xyz", grid_pair / "cmp.xyz", "-o", out, *GRID,
                       "--all-fields")
    assert code == 1
    assert errors(err) == [f"m3c2: error: {disk / 'g_distance.tif'}: No space left on device"]
    assert leftovers(disk) == []


@pytest.mark.parametrize("code_", [errno.ENOSPC, errno.EFBIG], ids=["ENOSPC", "EFBIG"])
def test_a_failing_raster_write_names_the_raster(grid_pair, tmp_path, capsys, monkeypatch, code_):
    folder = tmp_path / "outdir"
    folder.mkdir()
    (folder / "g_lod.tif").write_bytes(OLDER)
    real_write = os.write
    failed = []

    def write(fd, data):  # the lowest write primitive, failing for files of the output folder
        try:
            where = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:
            where = ""
        if where.startswith(str(folder)) and where.endswith(".tif"):
            failed.append(where)
            raise OSError(code_, os.strerror(code_))
        return real_write(fd, data)

    monkeypatch.setattr(os, "write", write)
    code, _, err = run(capsys, "compare", grid_pair / "ref.xyz", grid_pair / "cmp.xyz", "-o", folder / "g.laz",
                       *GRID)
    assert failed, "the rasters were not written through os.write"
    assert code == 1
    assert errors(err) == [f"m3c2: error: {folder / 'g_distance.tif'}: {os.strerror(code_)}"]
    assert (folder / "g_lod.tif").read_bytes() == OLDER
    assert leftovers(folder, keep={"g_lod.tif"}) == []


def test_a_staged_writers_warning_names_the_output_not_the_temporary(grid_pair, tmp_path, capsys):
    # A LAS table written beside rasters is written to a temporary; its QuantisationWarning named it.
    folder = tmp_path / "outdir"
    folder.mkdir()
    code, _, err = run(capsys, "compare", grid_pair / "ref.xyz", grid_pair / "cmp.xyz", "-o", folder / "g.laz",
                       *GRID)
    assert code == 0
    quantised = [line for line in err.splitlines() if "LAS stores the coordinates" in line]
    assert quantised and all(line.startswith(f"m3c2: warning: {folder / 'g.laz'}: ") for line in quantised)
    assert ".m3c2-tmp-" not in err
