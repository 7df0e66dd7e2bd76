"""Issue 42: the QGIS plugin's runner (qgis/m3c2kit_processing/runner.py) in the hostile harness,
without QGIS: its one QGIS name (QgsProcessingException) stubbed, the m3c2 it runs replaced by
fake executables that misbehave as a broken install, a wrapper script or a hung run would. Each
case ends, within its bound, with a clear exception or the right result; nothing holds QGIS."""
from __future__ import annotations

import os
import signal
import sys
import textwrap
import threading
import time
import types
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]


class FakeProcessingException(Exception):
    pass


@pytest.fixture(scope="module")
def runner():
    core = types.ModuleType("qgis.core")
    core.QgsProcessingException = FakeProcessingException
    saved = {name: sys.modules.get(name) for name in ("qgis", "qgis.core")}
    sys.modules["qgis"], sys.modules["qgis.core"] = types.ModuleType("qgis"), core
    sys.path.insert(0, str(ROOT / "qgis"))
    try:
        import importlib
        module = importlib.import_module("m3c2kit_processing.runner")
        yield module
    finally:
        sys.path.remove(str(ROOT / "qgis"))
        for name in ("m3c2kit_processing.runner", "m3c2kit_processing"):
            sys.modules.pop(name, None)
        for name, module in saved.items():
            if module is None:
                sys.modules.pop(name, None)
            else:
                sys.modules[name] = module


class Feedback:
    """QgsProcessingFeedback's methods the runner calls, recorded; Cancel after `cancel_after` s."""

    def __init__(self, cancel_after: float | None = None):
        self.started, self.cancel_after = time.monotonic(), cancel_after
        self.progress, self.errors, self.warnings, self.info = [], [], [], []

    def isCanceled(self):  # noqa: N802 - QGIS's name
        return self.cancel_after is not None and time.monotonic() - self.started > self.cancel_after

    def setProgress(self, value):  # noqa: N802
        self.progress.append(value)

    def reportError(self, text, fatal=False):  # noqa: N802
        self.errors.append(text)

    def pushWarning(self, text):  # noqa: N802
        self.warnings.append(text)

    def pushInfo(self, text):  # noqa: N802
        self.info.append(text)

    pushConsoleInfo = pushCommandInfo = pushInfo  # noqa: N815


def fake(tmp_path: Path, body: str) -> str:
    """An executable `m3c2` running `body` (Python)."""
    path = tmp_path / "m3c2"
    path.write_text(f"#!{sys.executable}\nimport os, signal, sys, time\n" + textwrap.dedent(body))
    path.chmod(0o755)
    return str(path)


#: The longest any case may take: a runner that hangs fails here instead of holding the suite.
BOUND_S = 30.0


def execute(runner, command, feedback, progress=True):
    """Run.execute() in a thread, failed when it outlives BOUND_S; its result or its exception."""
    outcome = {}

    def target():
        try:
            outcome["value"] = runner.Run(command, feedback, progress).execute()
        except BaseException as e:  # noqa: BLE001 - handed to the test
            outcome["error"] = e

    thread = threading.Thread(target=target, daemon=True)
    thread.start()
    thread.join(BOUND_S)
    assert not thread.is_alive(), f"the runner still runs {BOUND_S} s later: it hangs"
    if "error" in outcome:
        raise outcome["error"]
    return outcome["value"]


def test_a_child_that_ignores_sigterm_is_killed_after_cancel(runner, tmp_path, monkeypatch):
    monkeypatch.setattr(runner, "KILL_AFTER_S", 0.5)
    exe = fake(tmp_path, """
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        print("started", flush=True)
        while True:
            time.sleep(0.05)
        """)
    began = time.monotonic()
    with pytest.raises(FakeProcessingException, match="cancelled: m3c2 was killed \\(it ignored SIGTERM"):
        execute(runner, [exe], Feedback(cancel_after=0.3))
    assert time.monotonic() - began < 5


def test_cancel_of_a_well_behaved_run_says_nothing_was_written(runner, tmp_path):
    exe = fake(tmp_path, """
        signal.signal(signal.SIGTERM, lambda *a: sys.exit(1))
        while True:
            time.sleep(0.05)
        """)
    with pytest.raises(FakeProcessingException, match="stopped \\(SIGTERM\\) and wrote no output"):
        execute(runner, [exe], Feedback(cancel_after=0.2))


def test_a_grandchild_holding_the_pipes_does_not_hold_the_algorithm(runner, tmp_path, monkeypatch):
    monkeypatch.setattr(runner, "READERS_AFTER_EXIT_S", 0.3)
    exe = fake(tmp_path, """
        if os.fork() == 0:  # a background job of a wrapper: it inherits stdout and stderr
            time.sleep(10)
            os._exit(0)
        print("done", flush=True)
        """)
    began = time.monotonic()
    assert execute(runner, [exe], Feedback()).startswith("done")
    assert time.monotonic() - began < 5


def test_endless_output_without_a_line_break_stays_bounded(runner, tmp_path):
    exe = fake(tmp_path, """
        block = "x" * 65536
        for _ in range(160):  # 10 MiB on one "line"
            sys.stdout.write(block)
        sys.stdout.flush()
        """)
    out = execute(runner, [exe], Feedback())
    lines = out.split("\n")
    assert max(len(line) for line in lines) <= runner.LONGEST_LINE and sum(map(len, lines)) == 160 * 65536


@pytest.mark.parametrize("line", ['{"phase": "x", "percent": NaN}', '{"phase": "x", "percent": Infinity}',
                                  '{"phase": "x", "percent": -1e309}', '{"phase": 1}', '{"phase": "x", "percent": 250}'])
def test_malformed_progress_never_reaches_qgis_as_nan(runner, tmp_path, line):
    exe = fake(tmp_path, f"""
        sys.stderr.write({line!r} + "\\n")
        """)
    feedback = Feedback()
    execute(runner, [exe], feedback)
    assert all(0.0 <= p <= 100.0 for p in feedback.progress)  # 250 is 100; NaN and infinities dropped


def test_a_child_killed_by_a_signal_is_named(runner, tmp_path):
    exe = fake(tmp_path, """
        sys.stderr.write("Segmentation fault (core dumped)\\n")
        sys.stderr.flush()
        os.kill(os.getpid(), signal.SIGKILL)
        """)
    with pytest.raises(FakeProcessingException, match="m3c2 failed \\(killed by SIGKILL\\): Segmentation fault"):
        execute(runner, [exe], Feedback())


def test_binary_junk_and_an_error_line_give_one_clear_message(runner, tmp_path):
    exe = fake(tmp_path, """
        sys.stdout.buffer.write(bytes(range(256)) * 10)
        sys.stderr.write("\\xff\\xfe garbage\\nm3c2: error: r.laz: not a LAS file\\n")
        sys.exit(1)
        """)
    feedback = Feedback()
    with pytest.raises(FakeProcessingException, match="^r.laz: not a LAS file$"):
        execute(runner, [exe], feedback)
    assert feedback.errors == ["r.laz: not a LAS file"]


def test_a_missing_or_unrunnable_executable_is_a_clear_error(runner, tmp_path):
    with pytest.raises(FakeProcessingException, match="cannot run .*nope"):
        execute(runner, [str(tmp_path / "nope")], Feedback())
    plain = tmp_path / "plain"
    plain.write_text("not executable")
    with pytest.raises(FakeProcessingException, match="cannot run"):
        execute(runner, [str(plain)], Feedback())


@pytest.mark.parametrize("name", ["--help", "-o", "-", "--"])
def test_a_path_that_looks_like_an_option_is_passed_as_a_path(runner, name):
    assert runner.path_argument(name) == os.path.join(".", name)
    assert runner.path_argument("/data/" + name) == "/data/" + name


def test_many_lines_are_counted_not_all_kept(runner, tmp_path, monkeypatch):
    monkeypatch.setattr(runner, "MOST_LINES", 1000)
    exe = fake(tmp_path, """
        sys.stdout.write("line\\n" * 200000)
        """)
    out = execute(runner, [exe], Feedback(), progress=False)
    assert out.count("line") == 1000
    assert threading.active_count() < 50  # the readers ended
