"""docs/errors.md, "Interruption" (issue 15, "done when"): real `m3c2 compare` runs, tiled and
not, killed with every catchable signal and SIGKILL while reading, computing and writing, into a
folder that holds an older output. After each kill the older output is intact (same bytes); after
the next run into that folder nothing is left but its output (no temporary, no private folder, no
spill folder).

Each run is stopped at its phase by the testing aid M3C2_TEST_SIGNAL_AT=PHASE:SIGNAL
(m3c2kit.base.fault_hook: the run sends itself the signal there), not by sleeping. SIGKILL and SIGTERM
are sent in every mode at every phase; every other catchable signal once, dealt over the six
(mode, phase) cases so that each case also sees an ignored signal and three that end the process
(a few tens of runs in all). What each signal does is its disposition in `m3c2`:

- SIGINT, SIGTERM, SIGHUP, SIGQUIT: handled, `m3c2: error: interrupted by SIG...; no output
  written`, exit 1, nothing left even before the next run;
- ignored (SIGPIPE and SIGXFSZ by Python; SIGCHLD, SIGCONT, SIGURG, SIGWINCH by default): the
  run completes, its output replaces the older one whole;
- every other signal and SIGKILL end the process at once (killed by the signal); what it left is
  removed by the next run writing there (io.atomic.remove_stale).

Stop signals (SIGSTOP, SIGTSTP, SIGTTIN, SIGTTOU) pause a run without ending it and are not sent.
"""
from __future__ import annotations

import functools
import os
import resource
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from child_env import child_env
from hostile import finish
from posix_paths import needs

DATA = Path(__file__).resolve().parents[2] / "data" / "pairs" / "autzen-bmx"
PHASES = ("reading", "computing", "writing")
MODES = {"untiled": [], "tiled": ["--tile-size", "30"]}
ARGS = ["--normal-scale", "10", "--projection-scale", "5", "--max-depth", "10", "--threads", "2", "--quiet"]
OLDER = b"older output, to be kept\n"

HANDLED = {"SIGINT", "SIGTERM", "SIGHUP", "SIGQUIT"}
IGNORED = {"SIGPIPE", "SIGXFSZ", "SIGCHLD", "SIGCONT", "SIGURG", "SIGWINCH"}
STOPS = {"SIGSTOP", "SIGTSTP", "SIGTTIN", "SIGTTOU"}
EVERY_CASE = ("SIGKILL", "SIGTERM")
CASES = [(mode, phase) for mode in MODES for phase in PHASES]


def _name(number: int) -> str:
    if number == signal.SIGRTMIN:
        return "SIGRTMIN"
    if number == signal.SIGRTMAX:
        return "SIGRTMAX"
    return signal.Signals(number).name


def catchable() -> list[str]:
    """Every signal but the stops and the real-time ones between SIGRTMIN and SIGRTMAX (which
    behave as these two), plus SIGKILL."""
    numbers = sorted(s for s in signal.valid_signals() if s < signal.SIGRTMIN or s in (signal.SIGRTMIN, signal.SIGRTMAX))
    return [_name(s) for s in numbers if _name(s) not in STOPS]


def schedule(mode: str, phase: str) -> list[str]:
    """The signals sent to the runs of one case: EVERY_CASE, and the others dealt in turn over the
    cases, each class (handled, ignored, ending the process) on its own, so every case gets some
    of each class that has enough signals."""
    rest = [s for s in catchable() if s not in EVERY_CASE]
    dealt = [s for s in rest if s in HANDLED] + [s for s in rest if s in IGNORED] + \
            [s for s in rest if s not in HANDLED | IGNORED]
    mine = CASES.index((mode, phase))
    return list(EVERY_CASE) + [s for i, s in enumerate(dealt) if i % len(CASES) == mine]


def _no_core_dump():
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))


def start(out: Path, mode: str, cwd: Path, signal_at: str | None = None) -> subprocess.Popen:
    env = child_env(OMP_WAIT_POLICY="passive")  # idle OpenMP threads sleep: many runs share the cores
    env.pop("M3C2_TEST_SIGNAL_AT", None)
    if signal_at is not None:
        env["M3C2_TEST_SIGNAL_AT"] = signal_at
    argv = [sys.executable, "-m", "m3c2kit", "compare", str(DATA / "autzen-bmx-2010.las"),
            str(DATA / "autzen-bmx-2023.las"), "-o", str(out), *ARGS, *MODES[mode]]
    return subprocess.Popen(argv, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_no_core_dump)


def left_in(folder: Path) -> list[str]:
    return sorted(os.listdir(folder))


#: A private folder a killed run left is removed by the next run only where its lock dies with it.
_KILLED = needs("kernel_locks", why="a killed run's private folder is never proven abandoned, so it stays")
#: SIGHUP and SIGQUIT are m3c2's stops only where they exist (not on Windows, nor in the forced fallbacks).
_HUP = needs("posix_signals", why="SIGHUP and SIGQUIT end the process, unhandled")


@pytest.mark.slow
@_KILLED
@_HUP
@pytest.mark.parametrize("mode, phase", CASES)
def test_a_killed_run_keeps_the_older_output_and_the_next_run_leaves_nothing(tmp_path, mode, phase):
    signals = schedule(mode, phase)
    killed, ignored = tmp_path / "killed", tmp_path / "ignored"
    for folder in (killed, ignored):
        folder.mkdir()
        (folder / "out.csv").write_bytes(OLDER)
    # The runs of one case go together: each stops itself at the phase, whatever the others do
    # (a private folder of a live run is never removed by another).
    procs = {s: start((ignored if s in IGNORED else killed) / "out.csv", mode, tmp_path, f"{phase}:{s}")
             for s in signals}
    outcomes = {s: finish(p) for s, p in procs.items()}

    for s, (code, err) in outcomes.items():
        if s in HANDLED:
            assert (code, err) == (1, f"m3c2: error: interrupted by {s}; no output written\n"), (s, code, err)
        elif s in IGNORED:
            assert code == 0, (s, code, err)
        else:
            assert code == -getattr(signal, s), (s, code, err)  # ended by the signal at its phase
    assert (killed / "out.csv").read_bytes() == OLDER  # no kill touched the older output

    code, err = finish(start(killed / "out.csv", mode, tmp_path))  # the next run into the folder
    assert code == 0, err
    assert left_in(killed) == ["out.csv"]  # no .part, no private folder, no spill folder
    fresh = (killed / "out.csv").read_bytes()
    assert fresh.startswith(b"x,y,z,") and fresh != OLDER
    if any(s in IGNORED for s in signals):
        assert (ignored / "out.csv").read_bytes() == fresh  # the run went on: its output, whole
    assert left_in(ignored) == ["out.csv"]
    assert not list(tmp_path.glob("core*"))  # the signals with a core dump left none


def test_every_catchable_signal_is_sent_in_each_case_or_once():
    by_case = {case: schedule(*case) for case in CASES}
    sent = [s for signals in by_case.values() for s in signals]
    assert set(sent) == set(catchable()) and not set(sent) & STOPS
    assert {"SIGUSR1", "SIGUSR2", "SIGALRM", "SIGHUP", "SIGQUIT", "SIGSEGV", "SIGPIPE", "SIGRTMIN"} <= set(sent)
    for signals in by_case.values():
        assert set(EVERY_CASE) <= set(signals) and set(signals) & IGNORED
        assert len(set(signals) - HANDLED - IGNORED - {"SIGKILL"}) >= 2


def test_the_hook_is_inert_when_unset_or_malformed(tmp_path, monkeypatch):
    from m3c2kit.base import fault_hook

    for value in (None, "", "reading", "reading:SIGNOPE", "nophase:SIGTERM"):
        if value is None:
            monkeypatch.delenv(fault_hook.ENV, raising=False)
        else:
            monkeypatch.setenv(fault_hook.ENV, value)
        for phase in fault_hook.PHASES:
            fault_hook.checkpoint(phase)  # returns; a signal would end this test


@pytest.mark.slow
@pytest.mark.parametrize("delay", [0.15, 0.3, 0.45, 0.6, 0.9])
def test_a_sigint_while_a_run_starts_is_a_clean_interruption(tmp_path, delay):
    """Issue 42: a SIGINT early in `convert` was swallowed (exit 0 with the output) or, a little
    later, a raw KeyboardInterrupt: the imports a run starts with (laspy) were outside the handlers.
    Whenever it lands, the run ends as interrupted with nothing written, or it had finished and the
    copy is whole; killed by the signal (before Python's handler, or after the run, while the
    interpreter ends) it leaves no temporary beside the output."""
    import time
    whole = tmp_path / "whole"
    whole.mkdir()
    assert _convert(whole).wait(timeout=120) == 0
    expected = (whole / "copy.csv").read_bytes()
    child = _convert(tmp_path)
    time.sleep(_interpreter_startup() + delay)
    child.send_signal(signal.SIGINT)
    _, err = child.communicate(timeout=120)
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    made = sorted(set(left_in(tmp_path)) - {"whole"})
    if child.returncode == 1:
        assert "interrupted by SIGINT; no output written" in err and made == [], err
    else:
        assert child.returncode in (0, -signal.SIGINT), err
        assert made == ["copy.csv"] or (made == [] and child.returncode == -signal.SIGINT), made
        assert made == [] or (tmp_path / "copy.csv").read_bytes() == expected


def test_a_sigint_before_the_run_installs_its_handlers_is_the_commands_clean_interruption():
    """cli/command.py, the entry point: a stop while m3c2 imports itself is "interrupted; no
    output written" with exit status 1, not Python's KeyboardInterrupt traceback; importing the
    library leaves the caller's handler alone."""
    code = "import signal, time\nimport m3c2kit.cli.command\nsignal.raise_signal(signal.SIGINT)\ntime.sleep(5)\n"
    done = subprocess.run([sys.executable, "-c", code], env=child_env(), capture_output=True, text=True, timeout=60)
    assert done.returncode == 1 and done.stderr == "m3c2: error: interrupted by SIGINT; no output written\n", \
        done.stderr
    library = subprocess.run([sys.executable, "-c", "import signal, m3c2kit, m3c2kit.api\n"
                              "assert signal.getsignal(signal.SIGINT) is signal.default_int_handler"],
                             env=child_env(), capture_output=True, text=True, timeout=60)
    assert library.returncode == 0, library.stderr  # importing the library leaves the handler alone


@functools.cache
def _interpreter_startup() -> float:
    """The slowest of three starts of this interpreter doing nothing (its site module: .pth files,
    a system's site-packages; 0.05-0.25 s): a SIGINT before it is CPython's own "Fatal Python
    error: init_import_site", before any code of m3c2's. The delays above count from there."""
    import time
    slowest = 0.0
    for _ in range(3):
        start = time.monotonic()
        subprocess.run([sys.executable, "-c", "pass"], env=child_env(), check=True)
        slowest = max(slowest, time.monotonic() - start)
    return slowest


def _convert(folder: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "m3c2kit", "convert", str(DATA / "autzen-bmx-2010.las"), "-o",
                             str(folder / "copy.csv"), "-q"], cwd=folder, env=child_env(), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, preexec_fn=_no_core_dump)


def _newest_inputs(folder: Path) -> dict:
    """A compare output and regions: the inputs of the newest writing commands (issue 42)."""
    import json

    import numpy as np

    from m3c2kit.io import write_cloud_table
    rng = np.random.default_rng(3)
    n = 400
    xy = rng.random((n, 2)) * 10
    ones = np.ones(n)
    write_cloud_table(folder / "result.csv", np.column_stack([xy, np.zeros(n)]),
                      {"distance": rng.normal(0, 0.01, n), "lod": 0.03 * ones, "sigma1": 0.01 * ones,
                       "sigma2": 0.01 * ones, "n1": 20 * ones, "n2": 20 * ones, "significant": np.zeros(n)})
    (folder / "regions.geojson").write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"name": "r"},
         "geometry": {"type": "Polygon", "coordinates": [[[0, 0], [10, 0], [10, 10], [0, 10], [0, 0]]]}}]}))
    # two epochs of a rough surface, the second shifted: what m3c2 register aligns (issue 43)
    terrain = np.column_stack([xy, 0.3 * np.sin(xy[:, 0]) + 0.2 * np.cos(1.3 * xy[:, 1])])
    np.savetxt(folder / "epoch1.xyz", terrain)
    np.savetxt(folder / "epoch2.xyz", terrain + [0.01, -0.02, 0.03])
    return {"convert": ["convert", folder / "result.csv", "-o"],
            "variogram": ["variogram", folder / "result.csv", "--projection-scale", "1", "-o"],
            "aggregate": ["aggregate", folder / "result.csv", "--regions", folder / "regions.geojson", "-o"],
            "register": ["register", folder / "epoch1.xyz", folder / "epoch2.xyz", "--normal-scale", "2", "-o"],
            "pbm3c2": ["pbm3c2", folder / "epoch1.xyz", folder / "epoch2.xyz", "--normal-scale", "2", "--segment-angle",
                       "30", "--min-segment-points", "10", "--per-point", folder / "points.ply", "-o"]}


@pytest.mark.slow
@pytest.mark.parametrize("signal_name", [pytest.param("SIGKILL", marks=_KILLED), "SIGTERM", "SIGINT",
                                         pytest.param("SIGHUP", marks=_HUP)])
@pytest.mark.parametrize("command, output", [("convert", "out.ply"), ("variogram", "model.json"),
                                             ("aggregate", "table.csv"), ("register", "t.json"),
                                             ("pbm3c2", "pairs.las")])
def test_the_newest_commands_killed_while_writing_keep_the_older_output(tmp_path, command, output, signal_name):
    """Issue 42's harness: each newest writing command stopped at its write (the testing aid,
    M3C2_TEST_SIGNAL_AT=writing:SIGNAL) keeps the older output byte for byte (a handled signal
    leaves nothing beside it; SIGKILL's private folder is removed by the next run, which writes
    the output whole and leaves nothing else)."""
    argv = _newest_inputs(tmp_path)[command]
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    (out_dir / output).write_bytes(OLDER)

    def run(signal_at=None):
        env = child_env()
        env.pop("M3C2_TEST_SIGNAL_AT", None)
        if signal_at is not None:
            env["M3C2_TEST_SIGNAL_AT"] = signal_at
        return finish(subprocess.Popen([sys.executable, "-m", "m3c2kit", *map(str, argv), str(out_dir / output), "-q"],
                                       cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                       text=True, preexec_fn=_no_core_dump))

    code, err = run(f"writing:{signal_name}")
    if signal_name in HANDLED:
        assert code == 1 and err.endswith(f"m3c2: error: interrupted by {signal_name}; no output written\n"), err
        assert left_in(out_dir) == [output]
    else:
        assert code == -getattr(signal, signal_name), (code, err)
    assert (out_dir / output).read_bytes() == OLDER
    code, err = run()
    assert code == 0, err
    assert left_in(out_dir) == [output] and (out_dir / output).read_bytes() != OLDER


@pytest.mark.slow
def test_a_signal_the_caller_ignores_stays_ignored(tmp_path):
    """`nohup m3c2 ...` (SIGHUP ignored) and a shell's background job (SIGINT ignored): m3c2 must not
    make the signal end the run again; a SIGHUP at its write changes nothing, the output is whole."""
    def ignore_hup():
        _no_core_dump()
        signal.signal(signal.SIGHUP, signal.SIG_IGN)

    env = child_env()
    env["M3C2_TEST_SIGNAL_AT"] = "writing:SIGHUP"
    argv = [sys.executable, "-m", "m3c2kit", "compare", str(DATA / "autzen-bmx-2010.las"),
            str(DATA / "autzen-bmx-2023.las"), "-o", str(tmp_path / "out.csv"), *ARGS]
    code, err = finish(subprocess.Popen(argv, cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                        text=True, preexec_fn=ignore_hup))
    assert code == 0, err
    assert left_in(tmp_path) == ["out.csv"] and (tmp_path / "out.csv").read_bytes().startswith(b"x,y,z,")
