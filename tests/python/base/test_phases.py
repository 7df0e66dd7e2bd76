"""Progress over a run's phases (m3c2kit.base.phases): tqdm bars, no ETA before 3 %, silent off a
terminal unless forced, and the engine's callback drives it."""
from __future__ import annotations

import io
import re
import sys

import numpy as np

import m3c2kit
from m3c2kit.base.phases import ETA_AFTER, Phases


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_silent_off_a_terminal_unless_forced():
    pipe = io.StringIO()
    with Phases(stream=pipe).phase("reading", total=10) as step:
        step(10, 10)
    assert pipe.getvalue() == ""
    forced = io.StringIO()
    with Phases(enabled=True, stream=forced, mininterval=0).phase("reading", total=10) as step:
        step(10, 10)
    assert "reading" in forced.getvalue() and "100%" in forced.getvalue()
    tty = _Tty()
    with Phases(stream=tty, mininterval=0).phase("writing", total=4) as step:
        step(4, 4)
    assert "writing" in tty.getvalue()


def test_no_eta_before_three_percent():
    out = io.StringIO()
    with Phases(enabled=True, stream=out, mininterval=0).phase("distances", total=1000) as step:
        step(10, 1000)  # 1 %: no ETA yet
        early = out.getvalue()
        step(int(ETA_AFTER * 1000) + 10, 1000)
        later = out.getvalue()[len(early):]
    assert "ETA soon" in early and not re.search(r"<\d", early)
    assert re.search(r"\d\d:\d\d<\d\d:\d\d", later)


def test_engine_progress_drives_the_bar():
    rng = np.random.default_rng(0)
    ref = rng.uniform(0, 10, (3000, 3)) * [1, 1, 0.01]
    out = io.StringIO()
    with Phases(enabled=True, stream=out, mininterval=0) as p:
        with p.phase("distances") as step:
            m3c2kit.compare(ref, ref + [0, 0, 0.1], ref[::10], normal_scale=2, projection_scale=1, max_depth=1,
                            progress=step)
    text = out.getvalue()
    assert "distances" in text and "300/300" in text


def test_without_tqdm_each_phase_is_a_plain_line(monkeypatch):
    # The progress extra is optional: without tqdm a forced phase still says what it does.
    monkeypatch.setitem(sys.modules, "tqdm", None)
    monkeypatch.setitem(sys.modules, "tqdm.auto", None)  # `from tqdm.auto import tqdm` now fails
    out = io.StringIO()
    with Phases(enabled=True, stream=out, mininterval=0) as p:
        with p.phase("reading", total=2) as step:
            assert step(1, 2) is True
        with p.phase("distances") as step:
            m3c2kit.compare(np.eye(3) * 0 + np.arange(9).reshape(3, 3), np.arange(9).reshape(3, 3) + 0.1,
                            normal_scale=50, projection_scale=50, max_depth=5, progress=step)
    lines = out.getvalue().splitlines()
    assert lines[0] == "m3c2: reading..." and re.fullmatch(r"m3c2: reading done in \d+\.\d s", lines[1])
    assert lines[2] == "m3c2: distances..." and lines[3].startswith("m3c2: distances done in ")
    quiet = io.StringIO()
    with Phases(stream=quiet).phase("reading") as step:  # not a terminal: silent, as with tqdm
        step(1, 1)
    assert quiet.getvalue() == ""


def test_without_tqdm_the_command_line_prints_phase_lines(monkeypatch, tmp_path, capsys):
    from m3c2kit.cli.main import main
    from m3c2kit.io import write_cloud_table
    monkeypatch.setitem(sys.modules, "tqdm", None)
    monkeypatch.setitem(sys.modules, "tqdm.auto", None)
    rng = np.random.default_rng(1)
    xyz = np.column_stack([rng.uniform(0, 10, (2000, 2)), rng.normal(0, 0.01, 2000)])
    write_cloud_table(tmp_path / "a.ply", xyz, {})
    assert main(["normals", str(tmp_path / "a.ply"), "-o", str(tmp_path / "n.csv"), "--normal-scale", "2",
                 "--progress"]) == 0
    err = capsys.readouterr().err
    for phase in ("reading", "indexing, normals", "writing"):
        assert f"m3c2: {phase}...\n" in err and f"m3c2: {phase} done in " in err
