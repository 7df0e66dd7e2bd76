"""Attacker helpers for the tests of a hostile world (issue 31): another local user (``nobody``)
who can write in the output folder, a root-owned secret elsewhere, a run stopped at a known
point. Used by test_hostile_swap.py; every helper needs root (skip_unless_root says why not)."""
from __future__ import annotations

import os
import pwd
import signal
import tempfile
import time
import traceback
from pathlib import Path
from typing import Callable

import pytest

from m3c2kit.io.private import LOCK_NAME, PRIVATE_PREFIX

#: Names a writer may give a temporary in its private folder: `part` plus every output extension,
#: a tiled run's spill files, a new store's first files. The attacker plants a link at each.
PLANTED = ([f"part{ext}" for ext in (".csv", ".txt", ".xyz", ".ply", ".las", ".laz", ".copc.laz", ".tif",
                                     ".html", ".png", ".json", ".prm", ".npy")]
           + [f"{stem}-{tile}.bin" for stem in ("core", "normals", "reference", "compared", "result")
              for tile in range(4)]
           + ["tile_of.u32", "zarr.json", ".m3c2-lock"])

NOBODY = "nobody"


def skip_unless_root() -> None:
    """Skips the calling test, with the reason, where another user cannot be played."""
    if os.geteuid() != 0:
        pytest.skip("playing another local user (nobody) against a root-owned file needs root")
    try:
        pwd.getpwnam(NOBODY)
    except KeyError:
        pytest.skip(f"this system has no user {NOBODY!r} to play the attacker")


def as_nobody(fn: Callable, *args) -> None:
    """Runs fn(*args) in a forked child as the user nobody (no supplementary groups); raises
    AssertionError when it fails (its traceback is on stderr)."""
    user = pwd.getpwnam(NOBODY)
    pid = os.fork()
    if pid == 0:  # the child: never returns into the test runner
        code = 1
        try:
            os.setgroups([])
            os.setgid(user.pw_gid)
            os.setuid(user.pw_uid)
            fn(*args)
            code = 0
        except BaseException:  # noqa: BLE001 - reported through the exit status
            traceback.print_exc()
        finally:
            os._exit(code)
    _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0, f"the attacker's {fn.__name__} failed (see stderr)"


def open_folder(root: Path, name: str) -> Path:
    """A folder everyone can write in (0777, no sticky bit), as an output folder shared carelessly."""
    folder = root / name
    folder.mkdir()
    folder.chmod(0o777)
    return folder


def world_root() -> Path:
    """A folder nobody can reach (the test's tmp_path is in a 0700 folder), 0777; the caller removes it."""
    root = Path(tempfile.mkdtemp(prefix="m3c2-hostile-"))
    root.chmod(0o777)
    return root


def victim(tmp_path: Path, content: bytes = b"root's secret, never to be overwritten\n") -> Path:
    """A root-owned 0600 file in a 0700 folder, away from any output."""
    folder = tmp_path / "secret"
    folder.mkdir(mode=0o700)
    folder.chmod(0o700)
    path = folder / "victim"
    path.write_bytes(content)
    path.chmod(0o600)
    return path


def wait_stopped(proc, timeout: float = 120.0) -> None:
    """Waits until the process `proc` (subprocess.Popen) is stopped (state T in /proc/PID/stat)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            _, err = proc.communicate()
            raise AssertionError(f"the run ended (exit {proc.returncode}) before it stopped: {err}")
        try:
            with open(f"/proc/{proc.pid}/stat") as f:
                state = f.read().rsplit(")", 1)[1].split()[0]
        except OSError:
            state = ""
        if state in ("T", "t"):
            return
        time.sleep(0.02)
    proc.kill()
    raise AssertionError(f"the run never stopped within {timeout:g} s")


def swap_private_folders(folder: Path, target: Path) -> list[str]:
    """The swap attack, run as nobody: every private folder in `folder` renamed away and replaced
    by one of the attacker's, same name, holding links named as every temporary could be (PLANTED)
    to `target`, and a lock file of its own. Returns the names attacked."""
    names = sorted(n for n in os.listdir(folder) if n.startswith(PRIVATE_PREFIX))

    def attack() -> None:
        for i, name in enumerate(names):
            os.rename(folder / name, folder / f"moved-away-{i}")
            fake = folder / name
            fake.mkdir(mode=0o777)
            for planted in PLANTED:
                (fake / planted).symlink_to(target)
            (fake / LOCK_NAME).write_bytes(b"")

    as_nobody(attack)
    return names


def resume(proc) -> tuple[int, str]:
    """SIGCONT to a stopped run; its exit status and stderr once it ends."""
    os.kill(proc.pid, signal.SIGCONT)
    return finish(proc)


def finish(proc) -> tuple[int, str]:
    """A run's exit status and stderr once it ends (killed after 300 s)."""
    try:
        _, err = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return proc.returncode, err
