"""The one atomic writer (m3c2kit.io.atomic, issue 15 points 2 and 8; issue 31 items 1 and 2):
temporaries in a private folder reached through its descriptor, a symlink swap never redirects a
write, final mode by fchmod, long names; a folder written whole (staged_directory) and one pinned
(pinned_directory); stale folders removed on proof (their lock free), never by pid. The swap of a
real run's private folders by another user is test_hostile_swap.py."""
from __future__ import annotations

import os
import stat
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from m3c2kit.base.errors import CloudWriteError, UsageError
from m3c2kit.io.atomic import PRIVATE_PREFIX, atomic_output, pinned_directory, staged_directory, staged_outputs
from m3c2kit.base import portable
from m3c2kit.io.private import LOCK_NAME, pinnable
from child_env import child_env
from posix_paths import needs


@pytest.mark.slow
def test_a_symlink_swap_race_never_writes_the_victim(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    victim.chmod(0o600)
    target = tmp_path / "out.csv"
    stop = threading.Event()

    def attacker():
        # Someone who can write in the output folder keeps replacing the target, and any file
        # they can see in it, with a link to the victim.
        while not stop.is_set():
            for name in [target.name] + [p.name for p in tmp_path.iterdir() if p.name.endswith(".part")]:
                link = tmp_path / f".swap-{name}"
                try:
                    link.symlink_to(victim)
                    os.replace(link, tmp_path / name)
                except OSError:
                    pass

    thread = threading.Thread(target=attacker)
    thread.start()
    try:
        for i in range(100):
            with atomic_output(target) as tmp:
                time.sleep(0.002)  # a writer works before it opens its temporary: the attacker's window
                with open(tmp, "w") as f:
                    f.write(f"row {i}\n")
    finally:
        stop.set()
        thread.join()
    assert victim.read_text() == "precious" and stat.S_IMODE(victim.stat().st_mode) == 0o600
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(PRIVATE_PREFIX)]


def test_the_replaced_files_mode_is_kept(tmp_path):
    target = tmp_path / "out.csv"
    target.write_text("old")
    target.chmod(0o640)
    with atomic_output(target) as tmp:
        tmp.write_text("new")
    assert target.read_text() == "new" and stat.S_IMODE(target.stat().st_mode) == 0o640


def test_a_254_byte_output_name_works(tmp_path):
    target = tmp_path / ("x" * 250 + ".laz")
    assert len(target.name) == 254
    with atomic_output(target) as tmp:
        tmp.write_bytes(b"data")
    assert target.read_bytes() == b"data"


def test_a_failure_leaves_every_target_and_no_folder(tmp_path):
    a, b = tmp_path / "a.csv", tmp_path / "b.tif"
    a.write_text("older")
    with pytest.raises(RuntimeError):
        with staged_outputs([a, b]) as staged:
            staged[a].write_text("new")
            raise RuntimeError("boom")
    assert a.read_text() == "older" and not b.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.csv"]


@needs("kernel_locks", why="a killed run's private folder is never proven abandoned, so it stays")
def test_a_killed_runs_private_folder_is_removed_by_the_next_run(tmp_path):
    # A child creates its private folder and is killed (SIGKILL: nothing can clean up).
    code = ("import os, sys\nfrom m3c2kit.io.atomic import atomic_output\n"
            f"with atomic_output({str(tmp_path / 'out.csv')!r}) as tmp:\n"
            "    tmp.write_text('half')\n    os.kill(os.getpid(), 9)\n")
    subprocess.run([sys.executable, "-c", code], check=False)
    left = [p for p in tmp_path.iterdir() if p.name.startswith(PRIVATE_PREFIX)]
    assert len(left) == 1 and not (tmp_path / "out.csv").exists()
    with atomic_output(tmp_path / "out.csv") as tmp:
        tmp.write_text("whole")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.csv"]


# ------------------------------------------------------------------------------- stale folders

_HOLDER = """
import sys
from m3c2kit.io.atomic import atomic_output
with atomic_output(sys.argv[1]) as tmp:
    tmp.write_text("written by the live run\\n")
    print("ready", flush=True)
    sys.stdin.read()  # lives (its folder locked) until the test closes its stdin
"""


def _live_run(target: Path) -> subprocess.Popen:
    """Another process inside atomic_output(target): its private folder exists and is locked."""
    proc = subprocess.Popen([sys.executable, "-c", _HOLDER, str(target)], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True, env=child_env())
    assert proc.stdout.readline() == "ready\n"
    return proc


def _private(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith(PRIVATE_PREFIX))


@needs("kernel_locks", "folder_fds", why="a live run whose folder is renamed away stops (its writes went by name)")
def test_a_live_runs_folder_survives_a_sweep_whatever_pid_its_name_holds(tmp_path):
    # The pid an older version put in the name says nothing about a run in another PID namespace
    # or on another NFS client: a name with a pid that is dead here must not condemn a live run.
    proc = _live_run(tmp_path / "live.csv")
    try:
        (name,) = _private(tmp_path)
        os.rename(tmp_path / name, tmp_path / f"{PRIVATE_PREFIX}999999999-foreign")
        with atomic_output(tmp_path / "other.csv") as tmp:  # a new run sweeps the folder
            tmp.write_text("other")
        assert _private(tmp_path) == [f"{PRIVATE_PREFIX}999999999-foreign"]
    finally:
        proc.stdin.close()
        assert proc.wait(timeout=60) == 0
    # The live run was not disturbed: its output is whole, written through its folder's descriptor.
    assert (tmp_path / "live.csv").read_text() == "written by the live run\n"


@needs("kernel_locks", why="no folder is proven abandoned, so none is removed")
def test_an_abandoned_folder_is_removed_without_following_its_links(tmp_path):
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "keep.txt").write_text("keep")
    abandoned = tmp_path / f"{PRIVATE_PREFIX}1-abandoned"  # its lock file exists, no one holds it
    abandoned.mkdir(mode=0o700)
    (abandoned / LOCK_NAME).write_bytes(b"")
    (abandoned / "part.csv").write_text("half")
    (abandoned / "link").symlink_to(outside, target_is_directory=True)
    (abandoned / "sub").mkdir()
    (abandoned / "sub" / "chunk").write_bytes(b"0")
    with atomic_output(tmp_path / "x.csv") as tmp:
        tmp.write_text("x")
    assert _private(tmp_path) == [] and (outside / "keep.txt").read_text() == "keep"


def test_a_folder_without_a_lock_and_links_named_as_private_folders_are_left_alone(tmp_path):
    older = tmp_path / f"{PRIVATE_PREFIX}999999999-older"  # an older version's (no lock file), pid dead
    older.mkdir()
    (older / "part.laz").write_bytes(b"data")
    elsewhere = tmp_path / "elsewhere"  # what an attacker's links lead to, an unlocked lock in it
    elsewhere.mkdir()
    (elsewhere / LOCK_NAME).write_bytes(b"")
    (elsewhere / "precious").write_text("precious")
    (tmp_path / f"{PRIVATE_PREFIX}1-x").symlink_to(elsewhere, target_is_directory=True)
    linked_lock = tmp_path / f"{PRIVATE_PREFIX}1-lock-is-a-link"
    linked_lock.mkdir()
    (linked_lock / LOCK_NAME).symlink_to(elsewhere / LOCK_NAME)
    (linked_lock / "data").write_text("data")
    with atomic_output(tmp_path / "out.csv") as tmp:
        tmp.write_text("x")
    assert (older / "part.laz").read_bytes() == b"data"
    assert sorted(p.name for p in elsewhere.iterdir()) == [LOCK_NAME, "precious"]
    assert (tmp_path / f"{PRIVATE_PREFIX}1-x").is_symlink() and (linked_lock / "data").exists()


_LOCK_FREE = "import fcntl, os, sys\nfd = os.open(sys.argv[1], os.O_RDWR)\ntry:\n    fcntl.lockf(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)\nexcept OSError:\n    sys.exit(3)\n"


@needs("record_locks", why="there is no lock to drop")
def test_a_process_never_sweeps_its_own_folder_nor_drops_its_lock(tmp_path):
    # POSIX locks belong to the process: opening and closing its own folder's lock file would
    # drop it (and taking it would succeed), so the inner run must not even look at the outer's.
    with atomic_output(tmp_path / "outer.csv") as outer:
        with atomic_output(tmp_path / "inner.csv") as inner:
            inner.write_text("inner")
        (name,) = _private(tmp_path)
        lock = tmp_path / name / LOCK_NAME
        assert subprocess.run([sys.executable, "-c", _LOCK_FREE, str(lock)]).returncode == 3  # still held
        outer.write_text("outer")
    assert (tmp_path / "outer.csv").read_text() == "outer" and (tmp_path / "inner.csv").read_text() == "inner"


# -------------------------------------------------------------------- staged and pinned folders

def test_staged_directory_appears_whole_with_a_plain_folders_mode(tmp_path):
    target = tmp_path / "store"
    with staged_directory(target) as folder:
        assert not target.exists()
        (folder / "zarr.json").write_text("{}")
        (folder / "a").mkdir()
        (folder / "a" / "0").write_bytes(b"0")
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(target.stat().st_mode) == 0o777 & ~umask
    assert sorted(p.name for p in target.iterdir()) == ["a", "zarr.json"]  # no lock file left in it
    assert sorted(p.name for p in tmp_path.iterdir()) == ["store"]


@pytest.mark.parametrize("kind", ["a file", "a folder with a file", "a link to an empty folder"])
def test_staged_directory_refuses_an_occupied_target_before_its_body(tmp_path, kind):
    target = tmp_path / "out"
    if kind == "a file":
        target.write_text("keep")
    elif kind == "a folder with a file":
        target.mkdir()
        (target / "README").write_text("keep")
    else:
        (tmp_path / "empty").mkdir()
        target.symlink_to(tmp_path / "empty")
    before = sorted(p.name for p in tmp_path.rglob("*"))
    ran = []
    with pytest.raises(UsageError) as caught:
        with staged_directory(target):
            ran.append(True)
    assert str(caught.value) == f"{target} exists and is not empty; nothing in it is touched: choose another -o"
    assert not ran and sorted(p.name for p in tmp_path.rglob("*")) == before


def test_staged_directory_replaces_an_empty_folder_and_refuses_one_filled_meanwhile(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    with staged_directory(empty) as folder:
        (folder / "x").write_text("x")
    assert (empty / "x").read_text() == "x"
    late = tmp_path / "late"
    late.mkdir()
    with pytest.raises(UsageError, match="late exists and is not empty; nothing in it is touched: choose another -o"):
        with staged_directory(late) as folder:
            (folder / "x").write_text("mine")
            (late / "theirs").write_text("theirs")  # someone else writes there while the body runs
    assert sorted(p.name for p in late.iterdir()) == ["theirs"]
    assert _private(tmp_path) == []


@pytest.mark.parametrize("error", [KeyboardInterrupt, SystemExit, RuntimeError])
def test_staged_directory_leaves_nothing_when_its_body_fails(tmp_path, error):
    with pytest.raises(error):
        with staged_directory(tmp_path / "store") as folder:
            (folder / "half").write_text("half")
            raise error()
    assert list(tmp_path.iterdir()) == []


@pytest.mark.skipif(not pinnable(), reason="pinned paths need /proc/self/fd (Linux)")
def test_a_swapped_staging_folder_is_never_published(tmp_path):
    target = tmp_path / "store"
    with pytest.raises(CloudWriteError, match="replaced by someone else"):
        with staged_directory(target) as folder:
            assert str(folder).startswith("/proc/self/fd/")
            (name,) = _private(tmp_path)
            os.rename(tmp_path / name, tmp_path / "moved")  # the swap: ours away, another in its place
            (tmp_path / name).mkdir()
            (folder / "zarr.json").write_text("{}")  # still ours: through the descriptor
            assert (tmp_path / "moved" / "zarr.json").exists() and not (tmp_path / name / "zarr.json").exists()
    assert not target.exists() and list((tmp_path / "moved").iterdir()) == []


def test_pinned_directory_writes_where_it_was_opened_and_names_the_users_path(tmp_path):
    store = tmp_path / "store"
    store.mkdir()
    with pytest.raises(CloudWriteError) as caught:
        with pinned_directory(store) as pinned:
            os.rename(store, tmp_path / "moved")
            store.mkdir()  # another folder under the name
            (pinned / "chunk").write_text("0")
            raise CloudWriteError(f"{pinned / 'chunk'}: bad chunk")
    if pinnable():
        assert (tmp_path / "moved" / "chunk").exists() and not (store / "chunk").exists()
        assert str(caught.value) == f"{store / 'chunk'}: bad chunk"
    (tmp_path / "a-file").write_text("x")
    for missing, problem in ((tmp_path / "none", "no such directory"), (tmp_path / "a-file", "is not a directory")):
        with pytest.raises(CloudWriteError) as caught:
            with pinned_directory(missing):
                pass
        assert str(caught.value) == f"{missing}: {problem}"


def test_a_writers_error_names_the_target_never_a_pinned_path(tmp_path):
    target = tmp_path / "out.laz"
    with pytest.raises(CloudWriteError) as caught:
        with atomic_output(target) as tmp:
            raise CloudWriteError(f"{tmp}: cannot encode; in {tmp.parent}")
    assert str(caught.value) == f"{target}: cannot encode; in {tmp_path}"


def test_without_pinned_paths_a_swapped_folder_stops_the_run_before_any_rename(tmp_path, monkeypatch):
    monkeypatch.setattr(portable, "CAPS", portable.CAPS._replace(fd_paths=False))  # as on macOS: no /proc/self/fd
    target = tmp_path / "out.csv"
    target.write_text("older")
    with pytest.raises(CloudWriteError) as caught:
        with atomic_output(target) as tmp:
            assert not str(tmp).startswith("/proc/")
            (name,) = _private(tmp_path)
            os.rename(tmp_path / name, tmp_path / "moved")
            (tmp_path / name).mkdir()
            tmp.write_text("new")  # by name: into the other folder
    assert str(caught.value) == (f"{target}: not written: its private work folder in {str(tmp_path)!r} was "
                                 f"replaced by someone else during the run")
    assert target.read_text() == "older"
