"""docs/errors.md, "Fuzzing": the fuzz targets of tests/fuzz/ run on their seeds and a bounded,
seeded batch of mutants (the atheris campaign itself runs in scripts/test.sh), plus one
regression test per finding."""
from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest

FUZZ = Path(__file__).resolve().parents[2] / "fuzz"
sys.path.insert(0, str(FUZZ))

import random_fuzz  # noqa: E402
import targets  # noqa: E402

from m3c2kit.run.checks import threads_count  # noqa: E402
from m3c2kit.settings import build_params  # noqa: E402
from m3c2kit.cli.main import main  # noqa: E402
from m3c2kit.base.errors import CloudReadError, UsageError  # noqa: E402
from m3c2kit.io import read_cloud, write_cloud_table  # noqa: E402


@pytest.fixture(autouse=True)
def _scratch_cwd(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # random_fuzz writes crash-*.bin files into the working directory


@pytest.mark.parametrize("name", sorted(targets.TARGETS))
def test_seeds_are_accepted(name):
    for seed in targets.SEEDS[name]:
        targets.TARGETS[name](seed)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(targets.TARGETS))
def test_bounded_random_fuzz(name):
    failures = random_fuzz.fuzz(name, runs=400, seconds=20, seed=20241122)
    assert failures == [], f"{name} let an undocumented exception escape on {failures[0]!r:.300}"


# ------------------------------------------------------------------ regressions, one per finding

@pytest.mark.parametrize("argv, message", [
    # --seed -1 reached the engine binding and raised TypeError (a traceback, exit 1).
    (["--seed", "-1"], "--seed must be a non-negative integer, got -1"),
    # Integers wider than the engine's fields raised TypeError in the binding.
    (["--min-points", str(2**40)], "--min-points must be an integer >= 1, at most 4294967295"),
    (["--bootstrap", str(2**40)], "--bootstrap must be 0 (off) or >= 2 resamples, at most 100000"),
    (["--seed", str(2**64)], "--seed must be a non-negative integer, at most 18446744073709551615"),
    (["--threads", str(2**40)], "--threads must be 0 (all) or a positive integer, at most 2147483647"),
    # --threads -1 was accepted silently.
    (["--threads", "-1"], "--threads must be 0 (all) or a positive integer, got -1"),
])
def test_regression_integer_options_are_checked(tmp_path, capsys, argv, message):
    np.savetxt(tmp_path / "ref.xyz", np.random.default_rng(0).uniform(0, 1, (50, 3)))
    code = main(["compare", str(tmp_path / "ref.xyz"), str(tmp_path / "ref.xyz"), "-o", str(tmp_path / "o.csv"),
                 "--normal-scale", "0.5", "--projection-scale", "0.3", "--max-depth", "0.5", "--quiet", *argv])
    assert code == 2
    assert capsys.readouterr().err.startswith(f"m3c2: error: {message}")
    targets.cli_args(targets._argv("compare", "r.xyz", "c.xyz", "-o", "o.csv", "--normal-scale", "1",
                                   "--projection-scale", "1", "--max-depth", "1", *argv))


def test_regression_api_integer_fields():
    for kwargs in ({"seed": -5}, {"min_points": 2.5}, {"bootstrap": "x"}, {"min_points": float("nan")}):
        with pytest.raises(UsageError):
            build_params(normal_scale=1, projection_scale=1, max_depth=1, **kwargs)
    with pytest.raises(UsageError):
        threads_count(-2)


def test_regression_fifo_does_not_block(tmp_path):
    # read_cloud on a FIFO opened it and blocked forever waiting for a writer.
    os.mkfifo(tmp_path / "p.xyz")
    with pytest.raises(CloudReadError, match=r"p\.xyz: not a regular file$"):
        read_cloud(tmp_path / "p.xyz")


def test_regression_text_cut_in_its_last_line(tmp_path):
    # Said "fewer than three numeric columns", which hides that the file was truncated.
    (tmp_path / "t.xyz").write_text("1 2 3\n4 5 6\n7 8\n")
    with pytest.raises(CloudReadError, match=r"t\.xyz: line 3 has only 2 values, fewer than x, y, z "
                                             r"\(truncated file\?\)$"):
        read_cloud(tmp_path / "t.xyz")
    (tmp_path / "u.xyz").write_text("1 2 3\n4\n")
    with pytest.raises(CloudReadError, match=r"line 2 has only 1 value, fewer"):
        read_cloud(tmp_path / "u.xyz")


def test_regression_ply_short_write_names_the_cause(tmp_path, monkeypatch):
    # numpy's tofile reported a short write as "400 requested and 30 written" (no errno); the
    # writer now uses file.write, whose OSError carries ENOSPC/EFBIG.
    import errno

    from m3c2kit.io import ply

    real_open = open

    class Full:
        def __init__(self, f):
            self.f = f

        def write(self, data):
            if isinstance(data, memoryview):
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            return self.f.write(data)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.f.close()

    monkeypatch.setattr(ply, "open", lambda p, mode="r": Full(real_open(p, mode)), raising=False)
    with pytest.raises(Exception, match=r"out\.ply: No space left on device$"):
        write_cloud_table(tmp_path / "out.ply", np.zeros((5, 3)), {})
    assert list(tmp_path.iterdir()) == []
