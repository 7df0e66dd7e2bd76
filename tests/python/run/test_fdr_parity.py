"""--fdr in every mode (docs/algorithm.md, "False-discovery control"): the global ranking of every
core point's p-value gives a tiled run (two tile sizes), a --memory-limit run and a run on Dask the
in-memory run's bytes, q_value and significant_fdr included (test_modes_parity.py's approach)."""
from __future__ import annotations

import numpy as np
import pytest

from m3c2kit import engine
from m3c2kit.io import read_cloud
from test_modes_parity import every_mode, inputs
from test_run_modes import BASE, pair, scheduler  # noqa: F401 - the fixtures, shared


@pytest.mark.slow
@pytest.mark.parametrize("method", ["bh", "by"])
def test_fdr_in_every_mode(method, pair, scheduler, capsys, monkeypatch, tmp_path):  # noqa: F811
    runs = every_mode(tmp_path, [*inputs(pair), "-o", "change.ply", *BASE, "--core-spacing", "0.2", "--fdr", "0.05",
                                 "--fdr-method", method, "--float64"], scheduler, capsys, monkeypatch)
    assert "change.ply" in runs["memory"][0]
    table = read_cloud(tmp_path / "memory" / "change.ply").fields
    p, q, flag = table["p_value"], table["q_value"], table["significant_fdr"]
    finite = np.isfinite(p)
    assert finite.sum() > 100 and np.array_equal(np.isnan(q), ~finite)
    assert np.all(q[finite] >= p[finite]) and np.array_equal(flag, np.nan_to_num(q, nan=2.0) <= 0.05)
    # The ranking is global: every mode's q-values are those of all the run's p-values at once.
    assert np.array_equal(q, engine.fdr_q_values(p, method), equal_nan=True) and flag.sum() > 100


def test_fdr_memory_is_bounded_by_the_plan():
    from m3c2kit.base.errors import UsageError
    from m3c2kit.run import fdr
    fdr.check_memory(10**6, 2**30, 2**29)  # 32 MB of ranking beside 512 MiB in 1 GiB: fits
    with pytest.raises(UsageError, match="--memory-limit .* --fdr over 100000000 core points"):
        fdr.check_memory(10**8, 2**30, 2**29)  # 3.2 GB: refused, naming both options
