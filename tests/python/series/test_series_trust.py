"""A series store trusted as a monitoring archive (issue 31, item 3; docs/series.md "The store",
docs/errors.md "The series store"): create never deletes what -o holds, writers are locked out
of each other, a half-written variable is refused by every later step, epochs are identified by
their content (SHA-256), damage is found (`m3c2 series check`) and refused, never read as NaN.
The kills, concurrent runs and full disks of the hostile harness are in test_hostile_store.py."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

xr = pytest.importorskip("xarray")
zarr = pytest.importorskip("zarr")

from m3c2kit.base import fault_hook  # noqa: E402
from m3c2kit.cli.main import main  # noqa: E402
from m3c2kit.series import store as st  # noqa: E402
from m3c2kit.base import portable  # noqa: E402
from m3c2kit.series.lock import LOCK_NAME, lock_name  # noqa: E402
from posix_paths import needs  # noqa: E402

REPO = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(REPO / "validation"))
import series_synthetic as ss  # noqa: E402

PARAMS = ["--core-spacing", "0.5", "--normal-scale", "1", "--projection-scale", "1", "--max-depth", "1"]
#: 13 epochs of a 10 m square, a blob rising over epochs 3-9: 4D-OBC finds objects in it.
SCENARIO = ss.Scenario(extent=10.0, density=12.0, epochs=13, offset_epoch=20,
                       blobs=(ss.Blob(5.0, 5.0, 2.5, 0.4, 3, 9),),
                       landslide=ss.Landslide(2.0, 2.0, 1.0, 1.0, 0.0, 0.0, 2))
OBJECTS = ["--window-width", "6", "--window-min-size", "2", "--min-period", "2", "--min-segments", "3",
           "--max-cv", "5", "--thresholds", "0.5,0.9", "--quiet"]


@pytest.fixture(scope="module")
def epochs(tmp_path_factory):
    return ss.write(SCENARIO, tmp_path_factory.mktemp("epochs"))


@pytest.fixture(scope="module")
def base(epochs, tmp_path_factory):
    """A store of epochs 1-7 (chunks of 2 epochs: the last chunk is partial)."""
    out = tmp_path_factory.mktemp("base") / "base.zarr"
    assert main(["series", str(epochs[0]), *map(str, epochs[1:8]), "-o", str(out), *PARAMS, "--quiet",
                 "--epoch-chunk", "2", "--core-chunk", "150"]) == 0
    return out


def copy(store: Path, tmp_path: Path, name="s.zarr") -> Path:
    out = tmp_path / name
    shutil.copytree(store, out)
    return out


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    assert "Traceback" not in out.err, out.err
    return code, out.out, out.err


def tree(folder: Path) -> dict:
    """Every file below `folder` and its bytes."""
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


# ----------------------------------------------------------------------------------------------
# create never deletes: -o must be absent or empty, checked before any work


def _foreign_zarr(d: Path):
    g = zarr.open_group(str(d), mode="w", zarr_format=3, attributes={"tool": "another"})
    g.create_array("elevation", shape=(4,), dtype="f8")[:] = 1.0
    zarr.consolidate_metadata(str(d))
    (d / "README").write_text("field notes\n")


def _readme(d: Path):
    d.mkdir()
    (d / "README").write_text("field notes\n")


def _uncommitted(d: Path):
    zarr.open_group(str(d), mode="w", zarr_format=3, attributes={"format": st.FORMAT})  # never consolidated


@pytest.mark.parametrize("make", [_foreign_zarr, _readme, _uncommitted], ids=["foreign-zarr", "readme", "uncommitted"])
def test_create_refuses_a_non_empty_output_and_keeps_it(epochs, tmp_path, capsys, make):
    target = tmp_path / "out.zarr"
    make(target)
    before = tree(target)
    code, out, err = run(capsys, "series", epochs[0], epochs[1], "-o", target, *PARAMS, "--quiet")
    assert code == 2 and str(target) in err and "nothing in it is touched" in err
    assert "create it again" not in err and "--quiet" not in out
    assert tree(target) == before


@pytest.mark.slow
def test_create_refuses_a_file_and_a_damaged_store_keeping_its_epochs(epochs, base, tmp_path, capsys):
    file = tmp_path / "notes.txt"
    file.write_text("x")
    assert run(capsys, "series", epochs[0], epochs[1], "-o", file, *PARAMS)[0] == 2
    assert file.read_text() == "x"
    damaged = copy(base, tmp_path)
    (damaged / "distance" / "c" / "0" / "0").unlink()
    before = tree(damaged)
    code, _, err = run(capsys, "series", epochs[0], epochs[1], "-o", damaged, *PARAMS)
    assert code == 2 and "m3c2 series add" in err and "create it again" not in err
    assert tree(damaged) == before


def test_create_into_an_empty_folder(epochs, tmp_path, capsys):
    target = tmp_path / "empty.zarr"
    target.mkdir()
    assert run(capsys, "series", epochs[0], epochs[1], epochs[2], "-o", target, *PARAMS, "--quiet")[0] == 0
    assert xr.open_zarr(target).sizes["epoch"] == 2


def test_uncommitted_store_message_never_advises_creating_it_again(tmp_path, capsys):
    target = tmp_path / "u.zarr"
    _uncommitted(target)
    code, _, err = run(capsys, "series", "smooth", target)
    assert code == 1 and "no committed series store" in err and "create" not in err


# ----------------------------------------------------------------------------------------------
# the writer's lock

HOLDER = textwrap.dedent("""
    import sys, time
    from pathlib import Path
    from m3c2kit.series import lock
    held = lock.acquire(Path(sys.argv[1]), "test-holder")
    print("held", flush=True)
    time.sleep(60)
""")


def _hold(store: Path):
    child = subprocess.Popen([sys.executable, "-c", HOLDER, str(store)], stdout=subprocess.PIPE, text=True)
    assert child.stdout.readline().strip() == "held"
    return child


@pytest.mark.slow
@needs("kernel_locks", why="a killed holder's lock file stays: the next writer is refused until it is removed")
def test_a_second_writer_is_refused_naming_the_holder(base, epochs, tmp_path, capsys):
    store = copy(base, tmp_path)
    before = tree(store)
    child = _hold(store)
    try:
        for argv in (["add", store, epochs[8]], ["smooth", store, "--window", "3"],
                     ["objects", store, "-o", tmp_path / "o.csv", *OBJECTS]):
            code, _, err = run(capsys, "series", *argv)
            assert code == 1 and f"pid {child.pid}" in err and "step test-holder" in err, err
            assert not (tmp_path / "o.csv").exists()
        assert run(capsys, "series", "check", store)[0] == 0  # a reader is not locked out
    finally:
        child.kill()
        child.wait()
    before.pop(LOCK_NAME, None)
    after = tree(store)
    after.pop(LOCK_NAME, None)
    assert after == before
    # the holder was killed (SIGKILL): the kernel released its lock, nothing stale to remove
    assert run(capsys, "series", "add", store, epochs[8], "--quiet")[0] == 0
    assert st.committed_epochs(store) == 8


@pytest.mark.slow
@needs("folder_locks", "folder_fds", why="the store folder is not locked: a lock file removed by hand while a "
       "writer runs lets a second writer in (Windows refuses to remove a file another process holds open)")
@pytest.mark.parametrize("damage", ["removed", "replaced", "renamed"])
def test_the_lock_holds_whatever_happens_to_the_lock_file(damage, base, tmp_path, capsys):
    """Issue 42: `rm STORE/.m3c2-lock` while a writer ran let `series smooth` run beside it (the
    second writer made a new file and locked it). The store folder itself is locked too."""
    store = copy(base, tmp_path)
    child = _hold(store)
    try:
        lock_file = store / LOCK_NAME
        if damage == "removed":
            lock_file.unlink()
        elif damage == "replaced":
            lock_file.unlink()
            lock_file.write_text("")
        else:
            lock_file.rename(store / "elsewhere")
        for argv in (["smooth", store, "--window", "3"], ["kalman", store, "--process-noise", "1e-6"]):
            code, _, err = run(capsys, "series", *argv)
            assert code == 1 and "another m3c2 is writing this store" in err, err
        assert "smoothed_distance" not in xr.open_zarr(store)
    finally:
        child.kill()
        child.wait()
    assert run(capsys, "series", "smooth", store, "--window", "3", "--quiet")[0] == 0  # released with its holder


@needs("record_locks", "folder_locks", why="the test replaces fcntl.flock")
def test_the_lock_falls_back_to_the_file_where_a_folder_cannot_be_locked(base, tmp_path, monkeypatch):
    """NFS may refuse flock on a folder (ENOLCK): the file's lockf holds alone, as documented."""
    import errno
    import fcntl
    from m3c2kit.series import lock
    store = copy(base, tmp_path)

    def no_folder_lock(fd, how):
        raise OSError(errno.ENOLCK, "No locks available")

    monkeypatch.setattr(fcntl, "flock", no_folder_lock)
    held = lock.acquire(store, "first")
    try:
        assert held.folder is None
        with pytest.raises(st.StoreError, match="another writing step of this process"):
            lock.acquire(store, "second")
    finally:
        held.release()
    lock.acquire(store, "third").release()


def test_zarr_and_xarray_ignore_the_lock_file(base, tmp_path, capsys):
    store = copy(base, tmp_path)
    assert run(capsys, "series", "smooth", store, "--window", "3")[0] == 0
    assert (store / LOCK_NAME).exists() or not portable.kernel_locks()  # else removed at release
    consolidated = json.loads((store / "zarr.json").read_text())["consolidated_metadata"]["metadata"]
    assert not any(name.startswith(".m3c2") for name in consolidated)
    assert not any(name.startswith(".m3c2") for name in xr.open_zarr(store).variables)


# ----------------------------------------------------------------------------------------------
# half-written variables are refused, never silently replaced by distance


@pytest.mark.slow
def test_a_half_written_smoothed_distance_is_refused_by_every_step(base, tmp_path, capsys):
    store = copy(base, tmp_path)
    assert run(capsys, "series", "smooth", store, "--window", "3")[0] == 0
    st.set_rewriting(store, ["smoothed_distance"])  # what a kill inside smooth's publication leaves
    rerun = f"m3c2 series smooth {store} --window 3"
    for argv in (["objects", store, "-o", tmp_path / "o.csv", *OBJECTS],
                 ["objects", store, "-o", tmp_path / "o.csv", "--use", "smoothed", *OBJECTS],
                 ["changepoints", store, "--core", "3", "--window-width", "4"]):
        code, _, err = run(capsys, "series", *argv)
        assert code == 1 and "half-written" in err and rerun in err, err
    code, out, err = run(capsys, "series", "check", store)
    assert code == 1 and rerun in out
    assert run(capsys, "series", "objects", store, "-o", tmp_path / "raw.csv", "--use", "raw", *OBJECTS)[0] == 0
    assert run(capsys, "series", "smooth", store, "--window", "3")[0] == 0
    assert run(capsys, "series", "check", store)[0] == 0
    assert "rewriting" not in xr.open_zarr(store).attrs


@pytest.mark.slow
def test_sigterm_in_smooth_and_objects_keeps_the_previous_results(base, tmp_path, capsys, monkeypatch):
    store = copy(base, tmp_path)
    assert run(capsys, "series", "smooth", store, "--window", "3")[0] == 0
    assert run(capsys, "series", "objects", store, "-o", tmp_path / "o.csv", *OBJECTS)[0] == 0
    before = xr.open_zarr(store).load()
    table = (tmp_path / "o.csv").read_bytes()
    for phase in ("store-write", "store-commit"):
        for argv, kept in ((["smooth", store, "--window", "5"], "smoothed_distance"),
                           (["objects", store, "-o", tmp_path / "o.csv", "--use", "raw", *OBJECTS], "object")):
            monkeypatch.setenv(fault_hook.ENV, f"{phase}:SIGTERM")
            monkeypatch.setattr(fault_hook, "_fired", set())
            code, _, err = run(capsys, "series", *argv)
            monkeypatch.delenv(fault_hook.ENV)
            assert code == 1 and "interrupted by SIGTERM" in err and "no output written" not in err, err
            if phase == "store-write":  # before any chunk of the new variable: the old one is whole
                assert f"{kept} unchanged in {store}" in err
                after = xr.open_zarr(store).load()
                assert after[kept].equals(before[kept]) and after[kept].attrs == before[kept].attrs
                assert run(capsys, "series", "check", store)[0] == 0
            else:  # inside the publication: marked, refused, named
                assert f"{kept} is marked half-written" in err
                assert run(capsys, "series", "check", store)[0] == 1
                assert run(capsys, "series", *argv)[0] == 0
            assert (tmp_path / "o.csv").read_bytes() == table or kept == "object"


# ----------------------------------------------------------------------------------------------
# epochs identified by content


def test_a_touched_or_renamed_copy_is_skipped_naming_the_epoch(base, epochs, tmp_path, capsys):
    store = copy(base, tmp_path)
    os.utime(epochs[3], ns=(1, 2))  # touch: new mtime, same content
    renamed = tmp_path / "same_content_other_name.npy"
    shutil.copy(epochs[5], renamed)
    code, out, _ = run(capsys, "series", "add", store, epochs[3], renamed, epochs[8], epochs[8])
    assert code == 0 and st.committed_epochs(store) == 8
    assert f"{epochs[3]}: its content is already in {store} as epoch 2" in out
    assert f"{renamed}: its content is already in {store} as epoch 4 ({epochs[5]})" in out
    assert "an earlier file of this command" in out  # epochs[8] given twice: added once


def test_a_changed_file_at_a_stored_path_is_refused(base, epochs, tmp_path, capsys):
    store = copy(base, tmp_path)
    edited = tmp_path / "edited.npy"
    shutil.copy(epochs[8], edited)
    assert run(capsys, "series", "add", store, edited, "--quiet")[0] == 0
    stat = edited.stat()
    cloud = np.load(edited)
    cloud[0, 2] += 0.5  # same size
    np.save(edited, cloud)
    os.utime(edited, ns=(stat.st_atime_ns, stat.st_mtime_ns))  # same mtime: only the content tells
    before = tree(store)
    code, _, err = run(capsys, "series", "add", store, edited, epochs[9])
    assert code == 1 and str(edited) in err and "epoch 7" in err and "SHA-256" in err
    assert tree(store) == before  # refused before any work, epochs[9] not added either


@pytest.mark.slow
@pytest.mark.parametrize("where", ["distance/c/0/0", "lod/zarr.json"])
def test_a_fifo_in_the_store_is_named_and_never_opened(where, base, tmp_path, capsys):
    """Issue 42: a FIFO in place of a chunk hung `series check` and `series objects` (each opened it
    and waited for a writer). Every reader and writer names it as damage without opening it."""
    store = copy(base, tmp_path)
    (store / where).unlink()
    os.mkfifo(store / where)
    named = "not a regular file" if where.startswith("distance") else "zarr.json"
    for argv in (["check", store], ["smooth", store, "--window", "3"], ["changepoints", store, "--core", "0"],
                 ["objects", store, "-o", tmp_path / "o.csv", *OBJECTS], ["report", store, "-o", tmp_path / "r.html"]):
        done = subprocess.run([sys.executable, "-m", "m3c2kit", "series", *map(str, argv)], capture_output=True,
                              text=True, timeout=120)
        assert done.returncode == 1 and named in done.stdout + done.stderr, (argv, done.stdout, done.stderr)
        assert "Traceback" not in done.stderr
    assert not (tmp_path / "o.csv").exists() and not (tmp_path / "r.html").exists()


def _as_format_1(store: Path):
    """The store as the previous format wrote it: no hash column, no checksum codec, format_version 1."""
    shutil.rmtree(store / "source_sha256")
    g = zarr.open_group(str(store), mode="r+", use_consolidated=False)
    for name in sorted(g.array_keys()):
        old = g[name]
        data, meta, attrs = old[...], old.metadata, dict(old.attrs)
        del g[name]
        new = g.create_array(name, shape=old.shape, chunks=old.chunks, dtype=old.dtype, fill_value=meta.fill_value,
                             dimension_names=meta.dimension_names, compressors=st.codecs()[:1], attributes=attrs)
        new[...] = data
    g.attrs["format_version"] = 1
    zarr.consolidate_metadata(str(store))


@pytest.mark.parametrize("keep", ["hashes and checksums", "checksums"])
def test_a_lowered_format_version_switches_no_check_off(keep, base, tmp_path, capsys):
    """Issue 42: format_version set to 1 in a format 2 store's metadata switched the missing-chunk
    check off (`check` said sound with a chunk removed; `objects` ran on all-NaN distances). The store
    is checked by what it holds: format 2 content under version 1 is refused by every step."""
    store = copy(base, tmp_path)
    if keep == "checksums":
        shutil.rmtree(store / "source_sha256")
    g = zarr.open_group(str(store), mode="r+", use_consolidated=False)
    g.attrs["format_version"] = 1
    zarr.consolidate_metadata(str(store))
    shutil.rmtree(store / "distance" / "c")  # the damage the lowered version would hide
    before = tree(store)
    code, out, err = run(capsys, "series", "check", store)
    assert code == 1 and "format_version: 1, but the store holds format 2 content" in out + err
    for argv in (["smooth", store, "--window", "3"], ["objects", store, "-o", tmp_path / "o.csv", *OBJECTS],
                 ["kalman", store]):
        code, _, err = run(capsys, "series", *argv)
        assert code == 1 and "format_version: 1, but the store holds format 2 content" in err, (argv, err)
    assert tree(store) == before and not (tmp_path / "o.csv").exists()


def test_a_format_1_store_keeps_working(base, epochs, tmp_path, capsys):
    store = copy(base, tmp_path)
    _as_format_1(store)
    code, out, _ = run(capsys, "series", "check", store)
    assert code == 0 and "format version 1 stores no checksum" in out
    assert run(capsys, "series", "add", store, epochs[8], "--quiet")[0] == 0
    code, out, _ = run(capsys, "series", "add", store, epochs[8])  # same path, size, mtime: skipped
    assert code == 0 and "already in" in out and st.committed_epochs(store) == 8
    assert "source_sha256" not in xr.open_zarr(store).variables
    assert run(capsys, "series", "smooth", store, "--window", "3")[0] == 0


# ----------------------------------------------------------------------------------------------
# damage is found and refused, never read as NaN


def _missing(store):
    (store / "distance" / "c" / "1" / "3").unlink()


def _flipped(store):
    chunk = store / "distance" / "c" / "0" / "3"  # the partial last chunk: add reads it back
    data = bytearray(chunk.read_bytes())
    data[len(data) // 2] ^= 0x40
    chunk.write_bytes(bytes(data))


def _truncated(store):
    chunk = store / "distance" / "c" / "0" / "3"
    chunk.write_bytes(chunk.read_bytes()[:12])


@pytest.mark.slow
@pytest.mark.parametrize("damage,named", [(_missing, "chunk c/1/3"), (_flipped, "chunk c/0/3"),
                                          (_truncated, "chunk c/0/3")], ids=["missing", "flipped", "truncated"])
def test_a_damaged_chunk_is_named_by_check_and_refused(base, epochs, tmp_path, capsys, damage, named):
    store = copy(base, tmp_path)
    damage(store)
    code, out, err = run(capsys, "series", "check", store)
    assert code == 1 and f"array distance {named}" in out + err
    for argv in (["add", store, epochs[8]], ["smooth", store, "--window", "3"],
                 ["objects", store, "-o", tmp_path / "o.csv", *OBJECTS], ["changepoints", store, "--core", "0"],
                 ["report", store, "-o", tmp_path / "r.html"]):
        code, _, err = run(capsys, "series", *argv)
        assert code == 1 and "damaged: array distance" in err and named.split()[1] in err, (argv, err)
        assert "b'" not in err and "\\x" not in err, err  # issue 42: the codec's raw checksum bytes
    assert not (tmp_path / "o.csv").exists() and not (tmp_path / "r.html").exists()
    if damage is _flipped:
        assert "its checksum does not match" in out + err


# ----------------------------------------------------------------------------------------------
# an epoch or a list file of epochs that is a FIFO, a device or a folder: refused, never read


@pytest.mark.parametrize("kind", ["fifo", "device", "folder", "fifo-list"])
def test_a_special_epoch_or_list_file_is_refused_without_blocking(kind, base, tmp_path, capsys):
    store = copy(base, tmp_path)
    before = tree(store)
    if kind == "device":
        special = Path("/dev/zero")
    else:
        special = tmp_path / ("epochs.txt" if kind == "fifo-list" else "ep.las")
        os.mkfifo(special) if kind.startswith("fifo") else special.mkdir()
    code, _, err = run(capsys, "series", "add", store, special, "--quiet")
    assert code == 2 and f"the epoch {special}: " in err, err
    assert "does not exist" not in err
    assert tree(store) == before



@pytest.mark.parametrize("entry", ["missing", "fifo", "folder"])
def test_a_list_naming_a_missing_or_special_epoch_names_its_line(entry, base, epochs, tmp_path, capsys):
    """Issue 42: a list whose entry was missing was read as a point cloud ('no line with three
    numbers'). A list is told by its lines starting with a path; each entry is checked, by line."""
    store = copy(base, tmp_path)
    before = tree(store)
    bad = tmp_path / "gone.npy"
    if entry == "fifo":
        os.mkfifo(bad)
    elif entry == "folder":
        bad.mkdir()
    listing = tmp_path / "epochs.txt"
    listing.write_text(f"{epochs[8]}, 2024-01-09\ngone.npy, 2024-01-10\n")
    code, _, err = run(capsys, "series", "add", store, listing, "--quiet")
    assert code == 2 and f"{listing}:2: the epoch gone.npy" in err, err
    assert "three numbers" not in err
    assert tree(store) == before


# ----------------------------------------------------------------------------------------------
# red team (issue 31, item 3): variants found after the first implementation


def test_an_epoch_edited_between_its_hash_and_its_read_is_not_committed(base, epochs, tmp_path, capsys, monkeypatch):
    """The SHA-256 is taken before the file is read: an edit in between (size and mtime kept)
    would store one content's hash with another content's distances."""
    from m3c2kit.series import run as run_mod
    store = copy(base, tmp_path)
    edited = tmp_path / "late.npy"
    shutil.copy(epochs[9], edited)
    real = run_mod.read_cloud

    def edit_then_read(path, **kw):
        if Path(path) == edited:
            before = os.stat(edited)
            data = bytearray(edited.read_bytes())
            data[-1] ^= 0x01  # the last coordinate's lowest bit: same size, still a valid file
            edited.write_bytes(bytes(data))
            os.utime(edited, ns=(before.st_atime_ns, before.st_mtime_ns))
        return real(path, **kw)

    monkeypatch.setattr(run_mod, "read_cloud", edit_then_read)
    code, out, err = run(capsys, "series", "add", store, epochs[8], edited)
    assert code == 1 and f"{edited}: changed while this run read it" in err
    assert f"; epoch 7 committed in {store}, 1 not added" in err  # the failure says what was kept
    assert st.committed_epochs(store) == 8  # epochs[8], read before, is kept; the edited file is not
    assert run(capsys, "series", "check", store)[0] == 0


def _root_edit(edit):
    def damage(store: Path):
        root = json.loads((store / "zarr.json").read_text())
        edit(root, root["consolidated_metadata"]["metadata"], root["attributes"])
        (store / "zarr.json").write_text(json.dumps(root))
    return damage


def _root_text(cut):
    def damage(store: Path):
        (store / "zarr.json").write_text(cut((store / "zarr.json").read_text()))
    return damage


#: Root zarr.json files that are valid JSON of another shape (or no JSON): each gave a traceback
#: (KeyError, ValueError, TypeError) or let smooth/add run on arrays of mismatched lengths.
ROOT_DAMAGE = {
    "array-missing": (_root_edit(lambda r, m, a: m.pop("time")), "array time: missing from the committed metadata"),
    "length-mismatch": (_root_edit(lambda r, m, a: m["lod"]["shape"].__setitem__(1, 6)),
                        "array lod: 6 along epoch, the store has 7"),
    "dimensions-swapped": (_root_edit(lambda r, m, a: m["lod"].__setitem__("dimension_names", ["epoch", "core"])),
                           "array lod: dimensions"),
    "parameters-not-json": (_root_edit(lambda r, m, a: a.__setitem__("parameters", "{bad")),
                            "root attribute parameters: not a JSON object"),
    "reference-missing": (_root_edit(lambda r, m, a: a.pop("reference")), "root attribute reference: missing"),
    "rewriting-not-a-list": (_root_edit(lambda r, m, a: a.__setitem__("rewriting", 5)),
                             "root attribute rewriting: not a list"),
    "newer-format": (_root_edit(lambda r, m, a: a.__setitem__("format_version", 9)), "format version 9 of"),
    "version-not-a-number": (_root_edit(lambda r, m, a: a.__setitem__("format_version", "x")), "format version 'x'"),
    "root-a-json-list": (_root_text(lambda t: "[1, 2]"), "holds no Zarr group (a JSON list"),
    "root-truncated": (_root_text(lambda t: t[:100]), "is not valid JSON"),
}


@pytest.mark.slow
@pytest.mark.parametrize("variant", sorted(ROOT_DAMAGE))
def test_a_root_zarr_json_of_another_shape_is_named_and_refused(variant, base, epochs, tmp_path, capsys):
    damage, named = ROOT_DAMAGE[variant]
    store = copy(base, tmp_path)
    damage(store)
    before = tree(store)
    code, out, err = run(capsys, "series", "check", store)
    assert code == 1 and named in out + err
    for argv in (["smooth", store, "--window", "3"], ["add", store, epochs[8]],
                 ["report", store, "-o", tmp_path / "r.html"]):
        code, _, err = run(capsys, "series", *argv)
        assert code == 1 and err.startswith(f"m3c2: error: {store}: ") and named in err, (argv, err)
    assert tree(store) == before and not (tmp_path / "r.html").exists()


@pytest.mark.parametrize("plant", ["symlink", "hardlink", "fifo"])
def test_a_link_planted_as_the_lock_file_is_never_written_through(plant, base, tmp_path, capsys):
    """The writer truncates and rewrites its lock file (the holder's text): `.m3c2-lock ->
    /root/victim`, planted by anyone who may write in the store's folder, emptied the victim."""
    store = copy(base, tmp_path)
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    name = lock_name()  # LOCK_NAME, or the exclusive lock file where files cannot be locked
    (store / name).unlink(missing_ok=True)
    {"symlink": lambda p: p.symlink_to(victim), "hardlink": lambda p: os.link(victim, p),
     "fifo": os.mkfifo}[plant](store / name)
    before = tree(store)
    code, _, err = run(capsys, "series", "smooth", store, "--window", "3")
    assert code == 1 and err.startswith(f"m3c2: error: {store}: its lock file {name} is ") and "never makes" in err
    assert victim.read_text() == "precious\n" and tree(store) == before


def test_a_second_writer_in_the_same_process_is_refused(base, tmp_path, capsys):
    """POSIX locks are the process's: a second writing step in one process (two API calls, two
    threads) was granted the lock, and its release dropped the first writer's lock too."""
    from m3c2kit.series import lock
    store = copy(base, tmp_path)
    held = lock.acquire(store, "test-holder")
    try:
        code, _, err = run(capsys, "series", "smooth", store, "--window", "3")
        assert code == 1 and "another writing step of this process" in err and "step test-holder" in err
        holder = subprocess.run([sys.executable, "-c", HOLDER, str(store)], capture_output=True, text=True, timeout=60)
        assert holder.returncode != 0 and "test-holder" in holder.stderr  # the first lock still holds
    finally:
        held.release()
    assert run(capsys, "series", "smooth", store, "--window", "3")[0] == 0


@pytest.mark.slow
@pytest.mark.parametrize("action", ["smooth", "objects"])
def test_a_link_planted_as_the_staging_folder_is_never_followed(action, base, tmp_path, capsys):
    """`STORE/.m3c2-staging -> /elsewhere`: rmtree refuses a link, so the step wrote its new
    variable through it and moved the store's previous one into the link's target."""
    store = copy(base, tmp_path)
    assert run(capsys, "series", "smooth", store, "--window", "3")[0] == 0  # a previous variable to move
    assert run(capsys, "series", "objects", store, "-o", tmp_path / "first.csv", *OBJECTS)[0] == 0
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "notes.txt").write_text("keep\n")
    (store / ".m3c2-staging").symlink_to(elsewhere)
    argv = (["smooth", store, "--window", "5"] if action == "smooth"
            else ["objects", store, "-o", tmp_path / "second.csv", *OBJECTS])
    assert run(capsys, "series", *argv)[0] == 0
    assert sorted(p.name for p in elsewhere.iterdir()) == ["notes.txt"]
    assert not (store / ".m3c2-staging").exists() and not (store / ".m3c2-staging").is_symlink()
    assert run(capsys, "series", "check", store)[0] == 0
    if action == "smooth":
        assert xr.open_zarr(store)["smoothed_distance"].attrs["window"] == 5


@pytest.mark.parametrize("argv, words", [(["--core-chunk", "0"], "must be an integer >= 1, got '0'"),
                                         (["--epoch-chunk", "-1"], "must be an integer >= 1, got '-1'"),
                                         (["--threads", "-2"], "must be 0 (all) or a positive integer"),  # the table's
                                         (["--core-chunk", "9" * 30], "must be an integer >= 1, at most 4294967295")])
def test_a_chunk_or_thread_count_out_of_range_is_a_usage_error(argv, words, epochs, tmp_path, capsys):
    out = tmp_path / "s.zarr"
    code, _, err = run(capsys, "series", epochs[0], epochs[1], "-o", out, *PARAMS, *argv, "--quiet")
    assert code == 2 and argv[0] in err and words in err, err
    assert not out.exists()


def test_a_zarr_older_than_the_extra_asks_is_named(monkeypatch):
    from m3c2kit.base.errors import UsageError
    monkeypatch.delattr(zarr.Array, "with_config")
    with pytest.raises(UsageError, match=r"needs zarr >= 3\.1\.6 \(installed: .*pip install -U 'm3c2kit\[series\]'"):
        st.require_extra()


@pytest.mark.parametrize("argv, words", [
    (["report", "{s}", "-o", "{d}/rep.pdf"], "-o {d}/rep.pdf: the report is written as .html or .htm; give a name ending so"),
    (["objects", "{s}", "-o", "{d}/ob.json"], "-o {d}/ob.json: the objects table is written as .csv; give a name ending so"),
    (["check", "{d}/missing.zarr"], "{d}/missing.zarr: no such store (no file or folder of that name)"),
])
def test_an_output_named_for_another_content_and_a_missing_store_are_named(base, tmp_path, capsys, argv, words):
    """Hostile round 2: series report wrote HTML under any name, objects CSV under .json, and check
    called a path that is not there a damaged store."""
    code = main(["series", *(a.format(s=base, d=tmp_path) for a in argv)])
    err = capsys.readouterr().err
    assert code in (1, 2) and err == f"m3c2: error: {words.format(d=tmp_path)}\n", err
    assert list(tmp_path.iterdir()) == []
