"""The one atomic writer (m3c2kit.io.atomic, issue 15 points 2 and 8): temporaries in a private
folder, a symlink swap never redirects a write, final mode by fchmod, long names, stale folders of
killed runs removed by the next run."""
from __future__ import annotations

import os
import stat
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from m3c2kit.io.atomic import PRIVATE_PREFIX, atomic_output, staged_outputs


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
