"""Temporaries no one can hijack (issue 31, item 1; docs/errors.md "Temporaries"): a real `m3c2`
run as root writing into a folder everyone can write in is stopped where its private folders exist
and nothing is written yet (fault_hook phase `staging`, SIGSTOP); the user nobody renames every
private folder away and puts one of their own under its name, holding links named as every
temporary could be to a root-owned 0600 file elsewhere; the run is continued. The file is never
touched, and the run's outputs are those of an unattacked run, byte for byte (or the run failed
cleanly with no output). Every kind of output: point tables, rasters, the HTML report and its PNGs,
a classifier, an analysis table, a tiled run's spill folder, the series report, objects table and
a new store (io.atomic.staged_directory)."""
from __future__ import annotations

import os
import re
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from child_env import child_env
from hostile import open_folder, resume, skip_unless_root, swap_private_folders, victim, wait_stopped, world_root
from posix_paths import needs

REPO = Path(__file__).resolve().parents[3]
M3C2 = ["--projection-scale", "0.3", "--max-depth", "0.5", "--quiet"]
NORMALS = ["--normal-scale", "0.5"]
SERIES = ["--core-spacing", "1", "--normal-scale", "1", "--projection-scale", "1", "--max-depth", "1", "--quiet"]
OBJECTS = ["--window-width", "4", "--window-min-size", "2", "--min-period", "2", "--min-segments", "2",
           "--max-cv", "5", "--thresholds", "0.5,0.9", "--quiet"]


@pytest.fixture(autouse=True)
def _root_only():
    skip_unless_root()


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """Tiny clouds (400 points on a 0.1 grid) and classifier samples, seeded."""
    d = tmp_path_factory.mktemp("inputs")
    g = np.stack(np.meshgrid(np.arange(20) * 0.1, np.arange(20) * 0.1), -1).reshape(-1, 2)
    rng = np.random.default_rng(1)
    for name, z in (("ref", 0.0), ("cmp", 0.1)):
        np.savetxt(d / f"{name}.xyz", np.column_stack([g, z + rng.normal(0, 0.01, len(g))]), fmt="%.17g")
    np.savetxt(d / "ground.xyz", np.column_stack([rng.uniform(0, 4, (600, 2)), rng.normal(0, 0.02, 600)]))
    np.savetxt(d / "veg.xyz", rng.uniform(0, 4, (600, 3)))
    return d


@pytest.fixture(scope="module")
def series_inputs(tmp_path_factory):
    """A few synthetic epochs (validation/series_synthetic.py) and a store of them."""
    pytest.importorskip("xarray")
    pytest.importorskip("zarr")
    sys.path.insert(0, str(REPO / "validation"))
    import series_synthetic as ss
    from m3c2kit.cli.main import main
    d = tmp_path_factory.mktemp("series")
    scenario = ss.Scenario(extent=6.0, density=8.0, epochs=6, offset_epoch=3,
                           landslide=ss.Landslide(2.0, 4.0, 1.5, 1.0, 0.08, 0.003, 2),
                           blobs=(ss.Blob(4.0, 2.0, 1.0, 0.3, 1, 4),))
    epochs = ss.write(scenario, d / "epochs")
    store = d / "store.zarr"
    assert main(["series", str(epochs[0]), *map(str, epochs[1:]), "-o", str(store), *SERIES]) == 0
    return {"epochs": epochs, "store": store}


@pytest.fixture
def world(tmp_path):
    root = world_root()
    yield root
    shutil.rmtree(root, ignore_errors=True)


def _compare(i: Path, *extra) -> list:
    return ["compare", i / "ref.xyz", i / "cmp.xyz", *extra]


#: name -> argv (given the inputs' folder); outputs are written relative to the run's folder.
CASES = {
    "csv": lambda i: _compare(i, "-o", "out.csv", *NORMALS, *M3C2),
    "txt": lambda i: _compare(i, "-o", "out.txt", *NORMALS, *M3C2),
    "ply": lambda i: _compare(i, "-o", "out.ply", *NORMALS, *M3C2),
    "las": lambda i: _compare(i, "-o", "out.las", *NORMALS, *M3C2),
    "laz": lambda i: _compare(i, "-o", "out.laz", *NORMALS, *M3C2),
    "grid, report and its PNGs": lambda i: _compare(i, "-o", "out.csv", "--grid", "0.1", "--report", "r.html",
                                                    "--report-png", "p", *M3C2),
    "tiled (spill folder)": lambda i: _compare(i, "-o", "out.laz", "--tile-size", "1", *NORMALS, *M3C2),
    "classifier": lambda i: ["classify", "train", f"{i / 'ground.xyz'}=ground", f"{i / 'veg.xyz'}=vegetation",
                             "-o", "c.json", "--scales", "0.5,1", "--quiet"],
    "c2c table": lambda i: ["c2c", i / "ref.xyz", i / "cmp.xyz", "-o", "c2c.csv", "--model", "plane",
                            "--model-radius", "0.5", "--threads", "1"],
}
SERIES_CASES = {
    "series create (staged_directory)": lambda s, store: ["series", s["epochs"][0], s["epochs"][1], "-o",
                                                          "new.zarr", *SERIES],
    "series report": lambda s, store: ["series", "report", store, "-o", "report.html"],
    "series objects": lambda s, store: ["series", "objects", store, "-o", "objects.csv", *OBJECTS],
}


def _start(argv: list, cwd: Path, stop_at_staging: bool) -> subprocess.Popen:
    env = child_env(OMP_WAIT_POLICY="passive")
    env.pop("M3C2_TEST_SIGNAL_AT", None)
    if stop_at_staging:
        env["M3C2_TEST_SIGNAL_AT"] = "staging:SIGSTOP"
    return subprocess.Popen([sys.executable, "-m", "m3c2kit", *map(str, argv)], cwd=cwd, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


def _outputs(folder: Path) -> dict[str, Path]:
    """What a run left in `folder` but the attacker's work (moved folders, their fake folders)."""
    return {p.name: p for p in folder.iterdir() if not p.name.startswith((".", "moved-away-"))}


_UUID = re.compile(rb"[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}")


def _content(path: Path):
    if path.is_dir():  # a store: its variables' values (its history holds the time of the run)
        import xarray as xr
        with xr.open_zarr(path) as ds:
            return {k: v.values.tobytes() for k, v in ds.variables.items()}
    data = path.read_bytes()
    return _UUID.sub(b"UUID", data) if path.suffix == ".html" else data  # plotly's element ids are random


def _attacked_run(make_argv, world: Path, tmp_path: Path) -> None:
    """make_argv(folder): the command line of the baseline run, or the attacked one, in `folder`."""
    secret = victim(tmp_path)
    before = secret.read_bytes()
    base, hostile = open_folder(world, "base"), open_folder(world, "hostile")
    baseline = _start(make_argv(base), base, stop_at_staging=False)
    run = _start(make_argv(hostile), hostile, stop_at_staging=True)
    wait_stopped(run)
    attacked = swap_private_folders(hostile, secret)
    assert attacked, "the run had no private folder to attack"
    code, err = resume(run)
    _, base_err = baseline.communicate(timeout=300)
    assert baseline.returncode == 0, base_err

    assert secret.read_bytes() == before and stat.S_IMODE(secret.stat().st_mode) == 0o600
    assert secret.stat().st_uid == 0
    expected, got = _outputs(base), _outputs(hostile)
    if code == 0:
        assert sorted(got) == sorted(expected) and expected
        for name in expected:
            assert _content(got[name]) == _content(expected[name]), name
    else:  # refused cleanly for the swap (a folder renamed by name: a new store), one line, nothing written
        assert code == 1 and err.startswith("m3c2: error: ") and err.count("\n") == 1, (code, err)
        assert "was replaced by someone else" in err, err
        assert got == {}
    # The run's own temporaries, wherever the attacker moved its folders, were removed.
    for moved in hostile.glob("moved-away-*"):
        assert os.listdir(moved) == [], moved


#: Without /proc/self/fd a writer handed a path writes by the private folder's name: a folder
#: swapped in under it, holding links, has them written through before the seal finds the swap
#: (nothing is published). macOS, Windows and the forced fallbacks (docs/architecture.md, "Portability").
_PINNED = needs("fd_paths", why="writes by the private folder's name follow links planted in a folder swapped in")


@pytest.mark.slow
@_PINNED
@pytest.mark.parametrize("case", list(CASES))
def test_a_swapped_private_folder_redirects_no_write(inputs, world, tmp_path, case):
    _attacked_run(lambda folder: CASES[case](inputs), world, tmp_path)


@pytest.mark.slow
@_PINNED
@pytest.mark.parametrize("case", list(SERIES_CASES))
def test_a_swapped_private_folder_redirects_no_series_write(series_inputs, world, tmp_path, case):
    def make_argv(folder: Path) -> list:
        # Each run its own copy (objects writes its labels into it), named alike in both runs (the
        # report shows the name); hidden, it is no output to compare.
        shutil.copytree(series_inputs["store"], folder / ".store.zarr")
        return SERIES_CASES[case](series_inputs, ".store.zarr")

    _attacked_run(make_argv, world, tmp_path)
