"""Progress over a run's phases (m3c2kit.phases): tqdm bars, no ETA before 3 %, silent off a
terminal unless forced, and the engine's callback drives it."""
from __future__ import annotations

import io
import re

import numpy as np

import m3c2kit
from m3c2kit.phases import ETA_AFTER, Phases


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
