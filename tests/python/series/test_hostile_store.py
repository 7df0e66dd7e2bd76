"""The series store against a hostile world (issue 31, item 3; docs/errors.md "The series
store"): concurrent writers end with exact epoch counts; SIGKILL and SIGTERM at every write phase
(fault_hook `store-write`, `store-commit`) of create, add, smooth, objects, import, kalman and
tam3c2 leave a store that `m3c2 series check` accepts (or that names the half-written variables of
that step, with its rerun),
and the resumed or rerun step gives the uninterrupted run's store; a full disk leaves the store
at its last commit; damaged and foreign stores are refused and left as they were."""
from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

xr = pytest.importorskip("xarray")
zarr = pytest.importorskip("zarr")

from m3c2kit.base import fault_hook  # noqa: E402
from m3c2kit.cli.main import main  # noqa: E402
from m3c2kit.series import integrity  # noqa: E402
from m3c2kit.series import store as st  # noqa: E402
from posix_paths import needs  # noqa: E402

REPO = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(REPO / "validation"))
import series_synthetic as ss  # noqa: E402

PARAMS = ["--core-spacing", "0.5", "--normal-scale", "1", "--projection-scale", "1", "--max-depth", "1"]
CHUNKS = ["--epoch-chunk", "2", "--core-chunk", "150"]
SCENARIO = ss.Scenario(extent=10.0, density=12.0, epochs=15, offset_epoch=20,
                       blobs=(ss.Blob(5.0, 5.0, 2.5, 0.4, 3, 9),),
                       landslide=ss.Landslide(2.0, 2.0, 1.0, 1.0, 0.0, 0.0, 2))
OBJECTS = ["--window-width", "6", "--window-min-size", "2", "--min-period", "2", "--min-segments", "3",
           "--max-cv", "5", "--thresholds", "0.5,0.9", "--quiet"]
ARCHIVE = REPO / "tests" / "data" / "py4dgeo_series" / "analysis.zip"
REFERENCE_TIME = "2024-01-01T00:00"  # series_synthetic's epoch 0
TAM3C2 = ["--reference-time", REFERENCE_TIME, "--required-points", "5", "--window-ratio", "0.5,1"]
PHASES = ("store-write", "store-commit")


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    """The epochs and the uninterrupted stores every interrupted run is compared with."""
    root = tmp_path_factory.mktemp("world")
    e = ss.write(SCENARIO, root / "epochs")
    w = {"epochs": e, "root": root}
    w["base"] = root / "base.zarr"  # epochs 1-5
    assert main(["series", str(e[0]), *map(str, e[1:6]), "-o", str(w["base"]), *PARAMS, *CHUNKS, "--quiet"]) == 0
    w["added"] = root / "added.zarr"  # + epochs 6-12
    shutil.copytree(w["base"], w["added"])
    assert main(["series", "add", str(w["added"]), *map(str, e[6:13]), "--quiet"]) == 0
    w["smoothed"] = root / "smoothed.zarr"
    shutil.copytree(w["added"], w["smoothed"])
    assert main(["series", "smooth", str(w["smoothed"]), "--window", "3"]) == 0
    w["objects"] = root / "objects.zarr"
    shutil.copytree(w["smoothed"], w["objects"])
    assert main(["series", "objects", str(w["objects"]), "-o", str(root / "objects.csv"), *OBJECTS]) == 0
    assert len((root / "objects.csv").read_text().splitlines()) > 1, "no object: the comparison would be weak"
    w["imported"] = root / "imported.zarr"
    assert main(["series", "import", str(ARCHIVE), "-o", str(w["imported"])]) == 0
    # epochs 1-8 with their times (the list file series_synthetic wrote): what kalman and tam3c2 need
    listed = (root / "epochs" / "epochs.txt").read_text().splitlines()[1:9]
    (root / "timed.txt").write_text("".join(f"{root / 'epochs' / line}\n" for line in listed))
    w["timed"] = root / "timed.zarr"
    assert main(["series", str(e[0]), str(root / "timed.txt"), "-o", str(w["timed"]), *PARAMS, *CHUNKS,
                 "--quiet"]) == 0
    for name, options in (("kalman", []), ("tam3c2", TAM3C2)):
        w[name] = root / f"{name}.zarr"
        shutil.copytree(w["timed"], w[name])
        assert main(["series", name, str(w[name]), *options]) == 0
    return w


def same_values(x: Path, y: Path) -> None:
    a, b = xr.open_zarr(x), xr.open_zarr(y)
    assert set(a.variables) == set(b.variables)
    for name in a.variables:
        va, vb = a[name].values, b[name].values
        assert va.dtype == vb.dtype and va.shape == vb.shape, name
        if va.dtype.kind in "fiubM":  # bit for bit, NaN included
            assert va.tobytes() == vb.tobytes(), name
        else:
            assert np.array_equal(va, vb), name
    for name in st.DERIVED_VARIABLES:
        if name in a:
            assert a[name].attrs == b[name].attrs, name


def cli(*argv, env=None, capture=True):
    """`m3c2 ARGV` as a child process (a SIGKILL must kill a process of its own)."""
    return subprocess.run([sys.executable, "-m", "m3c2kit", *map(str, argv)], capture_output=capture, text=True,
                          env={**os.environ, **(env or {})}, timeout=300)


def check(store: Path) -> tuple[int, str]:
    """`m3c2 series check STORE` as (exit status, report), in this process (it only reads)."""
    found, damages = integrity.check(store)
    return int(bool(damages)), "\n".join([*found, *(f"damaged: {d}" for d in damages)])


# ----------------------------------------------------------------------------------------------
# SIGKILL and SIGTERM at every write phase of every step


def _step(name: str, w: dict, tmp: Path):
    """(argv, the store it writes, the resuming argv, the uninterrupted store, the variables it
    may leave half-written)."""
    e = w["epochs"]
    if name == "create":
        store = tmp / "c.zarr"
        return (["series", e[0], *e[1:6], "-o", store, *PARAMS, *CHUNKS, "--quiet"], store,
                ["series", "add", store, *e[1:6], "--quiet"], w["base"], None)
    if name == "add":
        store = tmp / "a.zarr"
        shutil.copytree(w["base"], store)
        argv = ["series", "add", store, *e[6:13], "--quiet"]
        return argv, store, argv, w["added"], None
    if name == "smooth":
        store = tmp / "s.zarr"
        shutil.copytree(w["added"], store)
        argv = ["series", "smooth", store, "--window", "3"]
        return argv, store, argv, w["smoothed"], ("smoothed_distance",)
    if name == "objects":
        store = tmp / "o.zarr"
        shutil.copytree(w["smoothed"], store)
        argv = ["series", "objects", store, "-o", tmp / "objects.csv", *OBJECTS]
        return argv, store, argv, w["objects"], ("object",)
    if name in ("kalman", "tam3c2"):  # all their variables published together
        store = tmp / f"{name}.zarr"
        shutil.copytree(w["timed"], store)
        argv = ["series", name, store, *(TAM3C2 if name == "tam3c2" else [])]
        resume = argv + (["--from-scratch"] if name == "kalman" else [])  # as series check says
        return argv, store, resume, w[name], st.KALMAN_VARIABLES if name == "kalman" else st.TAM3C2_VARIABLES
    store = tmp / "i.zarr"
    argv = ["series", "import", ARCHIVE, "-o", store]
    return argv, store, argv, w["imported"], None


@pytest.mark.slow
@pytest.mark.parametrize("signame", [pytest.param("SIGKILL", marks=needs("kernel_locks", why="a killed writer's lock is never dropped by the system: its lock file (a store's) or private folder stays")), "SIGTERM"])
@pytest.mark.parametrize("phase", PHASES)
@pytest.mark.parametrize("name", ["create", "add", "smooth", "objects", "import", "kalman", "tam3c2"])
def test_a_kill_at_every_write_phase_then_check_and_resume(world, tmp_path, monkeypatch, capsys, name, phase,
                                                           signame):
    argv, store, resume, whole, variables = _step(name, world, tmp_path)
    if signame == "SIGKILL":
        proc = cli(*argv, env={fault_hook.ENV: f"{phase}:SIGKILL"})
        assert proc.returncode == -signal.SIGKILL, (proc.returncode, proc.stderr)
    else:  # in this process, as main handles SIGTERM (docs/errors.md, "Interruption"): faster
        monkeypatch.setenv(fault_hook.ENV, f"{phase}:SIGTERM")
        monkeypatch.setattr(fault_hook, "_fired", set())
        code = main([str(a) for a in argv])
        monkeypatch.delenv(fault_hook.ENV)
        err = capsys.readouterr().err
        assert code == 1 and "interrupted by SIGTERM" in err and "Traceback" not in err, err
        if name in ("create", "add") and store.exists():
            assert "committed" in err and "no output written" not in err, err
            assert ("m3c2 series add" in err) if name == "create" else ("rerun the same command" in err), err
        if variables is not None:
            in_words = {"kalman": "Kalman variables", "tam3c2": "TAM3C2 variables"}.get(name, variables[0])
            assert any(v in err for v in variables) or in_words in err, err
            assert "no output written" not in err, err
    if store.exists():
        code, report = check(store)
        if code:  # only the variables the step was replacing may be marked, and named with its step
            damaged = [line for line in report.splitlines() if line.startswith("damaged:")]
            assert variables is not None and damaged, report
            assert {line.split(":")[1].strip() for line in damaged} <= set(variables), report
            assert all("half-written" in line and f"m3c2 series {name}" in line for line in damaged), report
    elif name == "create":
        resume = argv  # nothing at -o: the same command again
    assert main([str(a) for a in resume]) == 0
    assert check(store)[0] == 0
    same_values(whole, store)
    if name == "objects":
        assert (tmp_path / "objects.csv").read_bytes() == (world["root"] / "objects.csv").read_bytes()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")], "a private folder was left"


@pytest.mark.slow
@needs("kernel_locks", why="a killed writer's lock is never dropped by the system: its lock file (a store's) or private folder stays")
def test_a_killed_adds_unwritten_columns_are_never_published_by_the_next_step(world, tmp_path):
    """A kill after the chunks, before the commit, leaves arrays resized past the commit; the next
    writer (here smooth, whose commit consolidates every array) starts from the last commit."""
    store = tmp_path / "s.zarr"
    shutil.copytree(world["base"], store)
    proc = cli("series", "add", store, *world["epochs"][6:9], "--quiet", env={fault_hook.ENV: "store-commit:SIGKILL"})
    assert proc.returncode == -signal.SIGKILL
    code, report = check(store)
    assert code == 0 and "past the commit" in report, report
    assert main(["series", "smooth", str(store), "--window", "3"]) == 0
    assert st.committed_epochs(store) == 5 and xr.open_zarr(store)["smoothed_distance"].attrs["epochs"] == 5
    code, report = check(store)
    assert code == 0 and "past the commit" not in report, report


# ----------------------------------------------------------------------------------------------
# concurrent writers


def _stopped(argv):
    """A writer stopped by SIGSTOP when it is about to write (it holds the store's lock then)."""
    child = subprocess.Popen([sys.executable, "-m", "m3c2kit", *map(str, argv)], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True,
                             env={**os.environ, fault_hook.ENV: "store-write:SIGSTOP"})
    deadline = time.time() + 120
    while time.time() < deadline:
        state = Path(f"/proc/{child.pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        if state == "T":
            return child
        assert child.poll() is None, child.communicate()
        time.sleep(0.02)
    child.kill()
    raise AssertionError("the writer never reached store-write")


@pytest.mark.slow
@pytest.mark.parametrize("first,second", [("add", "add"), ("add", "smooth"), ("smooth", "objects")])
def test_a_second_writer_is_refused_and_the_counts_are_exact(world, tmp_path, first, second):
    e = world["epochs"]
    store = tmp_path / "s.zarr"
    shutil.copytree(world["base"] if first == "add" else world["added"], store)
    argvs = {"add": ["series", "add", store, *e[6:9], "--quiet"],
             "smooth": ["series", "smooth", store, "--window", "3"],
             "objects": ["series", "objects", store, "-o", tmp_path / "o.csv", *OBJECTS]}
    later = dict(argvs, add=["series", "add", store, *e[9:11], "--quiet"])
    child = _stopped(argvs[first])
    try:
        proc = cli(*later[second])
        assert proc.returncode == 1 and f"pid {child.pid}" in proc.stderr and f"step {first}" in proc.stderr
        assert "another m3c2 is writing" in proc.stderr, proc.stderr
    finally:
        child.send_signal(signal.SIGCONT)
        out, err = child.communicate(timeout=300)
    assert child.returncode == 0, err
    assert cli(*later[second]).returncode == 0  # the refused writer, once the first has finished
    ds = xr.open_zarr(store)
    n = ds.sizes["epoch"]
    assert n == {"add": 5 + 3 + (2 if second == "add" else 0)}.get(first, 12)
    assert len(set(ds["source_sha256"].values)) == n  # no epoch twice
    if second in ("smooth", "objects"):
        var = "smoothed_distance" if second == "smooth" else "object"
        assert ds[var].attrs["epochs"] == n
    assert check(store)[0] == 0


@pytest.mark.slow
@pytest.mark.parametrize("first,second", [("kalman", "tam3c2"), ("tam3c2", "kalman")])
def test_a_second_kalman_or_tam3c2_writer_is_refused_and_the_first_ends_whole(world, tmp_path, first, second):
    """While one of the two steps holds the store (stopped at store-write), the other is refused
    naming it; once the first has finished, the refused one runs, and the store is what the two
    uninterrupted runs make."""
    store = tmp_path / "s.zarr"
    shutil.copytree(world["timed"], store)
    argvs = {"kalman": ["series", "kalman", store], "tam3c2": ["series", "tam3c2", store, *TAM3C2]}
    child = _stopped(argvs[first])
    try:
        proc = cli(*argvs[second])
        assert proc.returncode == 1 and f"pid {child.pid}" in proc.stderr and f"step {first}" in proc.stderr
        assert "another m3c2 is writing" in proc.stderr, proc.stderr
    finally:
        child.send_signal(signal.SIGCONT)
        out, err = child.communicate(timeout=300)
    assert child.returncode == 0, err
    assert cli(*argvs[second]).returncode == 0
    assert check(store)[0] == 0
    ds = xr.open_zarr(store)
    for name in ("kalman", "tam3c2"):  # each equal to its uninterrupted run's
        want = xr.open_zarr(world[name])
        for var in st.KALMAN_VARIABLES if name == "kalman" else st.TAM3C2_VARIABLES:
            if var in want:
                assert ds[var].values.tobytes() == want[var].values.tobytes(), var


@pytest.mark.slow
def test_two_adds_started_together_end_with_every_epoch_once(world, tmp_path):
    e = world["epochs"]
    store = tmp_path / "s.zarr"
    shutil.copytree(world["base"], store)
    argvs = [["series", "add", store, *e[6:9], "--quiet"], ["series", "add", store, *e[9:12], "--quiet"]]
    children = [subprocess.Popen([sys.executable, "-m", "m3c2kit", *map(str, a)], stderr=subprocess.PIPE, text=True)
                for a in argvs]
    for argv, child in zip(argvs, children):
        err = child.communicate(timeout=300)[1]
        if child.returncode:  # refused while the other wrote: nothing of it acknowledged
            assert child.returncode == 1 and "another m3c2 is writing" in err, err
            assert cli(*argv).returncode == 0
    ds = xr.open_zarr(store)
    assert ds.sizes["epoch"] == 11 and len(set(ds["source_sha256"].values)) == 11
    assert check(store)[0] == 0


# ----------------------------------------------------------------------------------------------
# a full disk


@pytest.fixture
def full_disk(small_disk):
    """make(store) -> a copy of `store` on a small tmpfs (conftest.small_disk) with (almost) no space left."""

    def make(store: Path) -> Path:
        d = small_disk("4m")
        shutil.copytree(store, d / store.name)
        free = shutil.disk_usage(d).free
        with open(d / "filler", "wb") as f:
            f.write(b"\0" * max(0, free - 8192))
        return d / store.name

    return make


@pytest.mark.slow
def test_a_full_disk_leaves_every_step_at_its_last_commit(world, tmp_path, capsys, full_disk):
    e = world["epochs"]
    store = full_disk(world["smoothed"])
    before = xr.open_zarr(store).load()
    for argv, kept in ((["add", store, *e[13:15]], f"no epoch of this run committed; {store} holds 12 epoch(s)"),
                       (["smooth", store, "--window", "5"], f"smoothed_distance unchanged in {store}"),
                       (["objects", store, "-o", tmp_path / "o.csv", *OBJECTS], f"{store} unchanged (it has no object)")):
        code = main(["series", *map(str, argv)])
        err = capsys.readouterr().err
        assert code == 1 and "No space left on device" in err and kept in err and "Traceback" not in err, err
        assert len(err.strip().splitlines()) == 1
        assert check(store)[0] == 0
        assert xr.open_zarr(store).load().identical(before)
    assert not (tmp_path / "o.csv").exists()
    (store.parent / "filler").unlink()
    assert main(["series", "add", str(store), *map(str, e[13:15]), "--quiet"]) == 0
    assert st.committed_epochs(store) == 14 and check(store)[0] == 0


# ----------------------------------------------------------------------------------------------
# damaged and foreign stores


def _delete_root_json(s: Path):
    (s / "zarr.json").unlink()


def _delete_array_json(s: Path):
    (s / "lod" / "zarr.json").unlink()


def _partial_copy(s: Path):
    """As an interrupted copy leaves it: the files after the first half (in copy order) absent."""
    files = sorted(p for p in s.rglob("*") if p.is_file() and p.parent != s)
    for p in files[len(files) // 2:]:
        p.unlink()


def _truncated_chunks(s: Path):
    """Chunks that every step reads (decode errors are found as chunks are read): the first core
    points' x (add reads the core points) and distance (the analyses and the report)."""
    for chunk in (s / "x" / "c" / "0", s / "distance" / "c" / "0" / "0"):
        chunk.write_bytes(chunk.read_bytes()[:-3])


@pytest.mark.slow
@pytest.mark.parametrize("damage", [_delete_root_json, _delete_array_json, _partial_copy, _truncated_chunks])
def test_a_damaged_store_is_refused_by_every_step_and_left_as_it_is(world, tmp_path, capsys, damage):
    store = tmp_path / "s.zarr"
    shutil.copytree(world["added"], store)
    damage(store)
    before = {p: p.read_bytes() for p in store.rglob("*") if p.is_file() and p.name != ".m3c2-lock"}
    code, report = check(store)
    assert code == 1 and ("damaged" in report or "not a series store" in report), report
    e = world["epochs"]
    for argv in (["add", store, e[13]], ["smooth", store, "--window", "3"],
                 ["objects", store, "-o", tmp_path / "o.csv", *OBJECTS], ["changepoints", store, "--core", "0"],
                 ["report", store, "-o", tmp_path / "r.html"], ["check", store]):
        code = main(["series", *map(str, argv)])
        err = capsys.readouterr().err
        assert code == 1 and str(store) in err and "Traceback" not in err, (argv, err)
        assert "create it again" not in err
    assert {p: p.read_bytes() for p in store.rglob("*") if p.is_file() and p.name != ".m3c2-lock"} == before
    assert not (tmp_path / "o.csv").exists() and not (tmp_path / "r.html").exists()


def _foreign_zarr(d: Path):
    g = zarr.open_group(str(d), mode="w", zarr_format=3, attributes={"tool": "another"})
    g.create_array("distance", shape=(4, 2), dtype="f8")[:] = 1.0
    zarr.consolidate_metadata(str(d))


def _readme_folder(d: Path):
    d.mkdir()
    (d / "README").write_text("field notes\n")


@pytest.mark.parametrize("make", [_foreign_zarr, _readme_folder])
def test_a_foreign_store_is_refused_and_untouched(world, tmp_path, capsys, make):
    store = tmp_path / "foreign"
    make(store)
    before = {p: p.read_bytes() for p in store.rglob("*") if p.is_file()}
    e = world["epochs"]
    for argv in (["add", store, e[1]], ["smooth", store], ["objects", store, "-o", tmp_path / "o.csv"],
                 ["changepoints", store, "--core", "0"], ["report", store, "-o", tmp_path / "r.html"],
                 ["check", store], [e[0], e[1], "-o", store, *PARAMS], ["import", ARCHIVE, "-o", store]):
        code = main(["series", *map(str, argv)])
        err = capsys.readouterr().err
        assert code in (1, 2) and str(store) in err and "Traceback" not in err, (argv, err)
    assert {p: p.read_bytes() for p in store.rglob("*") if p.is_file()} == before
