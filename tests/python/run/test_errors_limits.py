"""docs/errors.md, "Run limits" (issue 15, points 3 and 5): thread counts that crashed the
interpreter, a process thread limit that made libgomp abort, a bootstrap without a bound that
ignored SIGINT and SIGTERM. Each runs in a child process: a crash there fails the test instead
of killing pytest."""
from __future__ import annotations

import select
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
from child_env import child_env

from m3c2kit import _core, api
from m3c2kit.base.errors import UsageError

PARAMS = dict(normal_scale=1.0, projection_scale=0.5, max_depth=2.0, bootstrap=20)


def rough_pair(n=3000, seed=3):
    rng = np.random.default_rng(seed)
    out = []
    for lift in (0.0, 0.05):
        xy = rng.uniform(0, 10, (n, 2))
        out.append(np.column_stack([xy, 0.3 * np.sin(xy[:, 0]) + lift + rng.normal(0, 0.02, n)]))
    return out


@pytest.fixture(scope="module")
def pair_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("limits")
    ref, cmp_ = rough_pair()
    np.save(d / "ref.npy", ref)
    np.save(d / "cmp.npy", cmp_)
    expected = api.compare(ref, cmp_, ref[::7], threads=1, **PARAMS)
    np.save(d / "expected.npy", np.column_stack([expected.distance, expected.lod]))
    return d


CHILD = textwrap.dedent("""
    import sys, numpy as np
    from m3c2kit import api
    d, threads = sys.argv[1], [int(t) for t in sys.argv[2:]]
    ref, cmp_ = np.load(d + "/ref.npy"), np.load(d + "/cmp.npy")
    expected = np.load(d + "/expected.npy")
    for t in threads:
        r = api.compare(ref, cmp_, ref[::7], threads=t, normal_scale=1.0, projection_scale=0.5, max_depth=2.0,
                        bootstrap=20)
        got = np.column_stack([r.distance, r.lod])
        assert np.array_equal(got.view(np.uint64), expected.view(np.uint64)), t
        print("same bits with threads =", t, flush=True)
""")


def run_child(args, timeout=300):
    return subprocess.run([sys.executable, "-c", CHILD, *map(str, args)], capture_output=True, text=True,
                          env=child_env(), timeout=timeout)


def test_huge_thread_counts_run_with_the_same_bits(pair_files):
    """threads=10**8 killed the interpreter and --threads 100000 ended in SIGSEGV (libgomp asked
    for that many threads); now clamped to 4 per hardware thread (at most 1024)."""
    done = run_child([pair_files, 100_000, 10**8, 2**31 - 1])
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.count("same bits") == 3


def test_threads_beyond_the_engine_int_are_a_usage_error():
    ref, cmp_ = rough_pair(200)
    with pytest.raises(UsageError, match=r"--threads must be 0 \(all\) or a positive integer, at most 2147483647"):
        api.compare(ref, cmp_, threads=2**31, **PARAMS)


# A process thread limit (RLIMIT_NPROC) is tested in the engine's suite,
# tests/cpp/test_run_limits.cpp::AProcessThreadLimitRunsWithTheThreadsItCanCreate: the limit
# binds only a user other than root, and this interpreter lives under /root.


def test_bootstrap_above_the_maximum_is_refused_before_the_run():
    """--bootstrap 1000000000 was accepted (and then ran for days, 8 GB per thread)."""
    assert _core.MAX_BOOTSTRAP_SAMPLES == 100_000
    ref, cmp_ = rough_pair(200)
    with pytest.raises(UsageError, match="at most 100000, got 1000000000"):
        api.compare(ref, cmp_, **dict(PARAMS, bootstrap=10**9))
    api.compare(ref, cmp_, **dict(PARAMS, bootstrap=_core.MAX_BOOTSTRAP_SAMPLES, projection_scale=0.05))


_HOOK = textwrap.dedent("""
    import sys
    import m3c2kit.engine as engine
    original = engine.compute
    def compute(*args, progress=None, **kwargs):
        def first_poll(done, total):
            if not getattr(first_poll, "seen", False):
                first_poll.seen = True
                print("ENGINE-RUNNING", file=sys.stderr, flush=True)
            return True if progress is None else progress(done, total)
        return original(*args, progress=first_poll, **kwargs)
    engine.compute = compute
    from m3c2kit.cli.main import main
    sys.exit(main(sys.argv[1:]))
""")


@pytest.fixture(scope="module")
def one_long_core_point(tmp_path_factory):
    """One core point whose cylinders hold 50,000 points each: 100,000 resamples take minutes."""
    d = tmp_path_factory.mktemp("bootstrap")
    rng = np.random.default_rng(1)
    for name, lift in (("ref", 0.0), ("cmp", 0.5)):
        np.save(d / f"{name}.npy", np.column_stack([rng.uniform(-0.1, 0.1, (50_000, 2)),
                                                    lift + rng.uniform(-0.1, 0.1, 50_000)]))
    np.save(d / "core.npy", np.zeros((1, 3)))
    (d / "hook.py").write_text(_HOOK)
    return d


def _readline(stream, timeout: float) -> str:
    ready, _, _ = select.select([stream], [], [], timeout)
    return stream.readline() if ready else ""


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_long_bootstrap_stops_on_a_signal(one_long_core_point, tmp_path, sig):
    """The engine checked for cancellation only between blocks of core points: inside one core
    point's bootstrap it ignored SIGINT and SIGTERM. Now the resample loop polls the progress
    callback (where Python notices signals) every 0.1 s."""
    d = one_long_core_point
    out = tmp_path / "out.csv"
    proc = subprocess.Popen([sys.executable, str(d / "hook.py"), "compare", str(d / "ref.npy"), str(d / "cmp.npy"),
                             "--core", str(d / "core.npy"), "-o", str(out), "--normal-source", "vertical",
                             "--projection-scale", "1", "--max-depth", "2", "--bootstrap", "100000", "--quiet"],
                            stderr=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=child_env())
    try:
        first = _readline(proc.stderr, 60)  # the first poll comes from inside the bootstrap
        assert first == "ENGINE-RUNNING\n", first
        time.sleep(0.3)
        assert proc.poll() is None
        proc.send_signal(sig)
        code = proc.wait(timeout=30)
        rest = proc.stderr.read()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert code == 1, rest
    assert rest == f"m3c2: error: interrupted by {sig.name}; no output written\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == []
