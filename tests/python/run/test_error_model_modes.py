"""--error-model in every mode (issue 34): a tiled run (two tile sizes), a --memory-limit run and a
run on a Dask cluster write the in-memory run's output byte for byte (the model's sigma_c^2 is an
engine parameter, pickled with Params to every tile and worker), and the option changes the LOD
as docs/algorithm.md says."""
from __future__ import annotations

import numpy as np
import pytest

from m3c2kit.analysis.error_model import Component, ErrorModel, save
from m3c2kit.io import read_cloud
from test_modes_parity import every_mode, inputs
from test_run_modes import BASE, pair, scheduler  # noqa: F401 - the fixtures, shared


@pytest.mark.slow
def test_error_model_in_every_mode(pair, scheduler, capsys, monkeypatch, tmp_path):  # noqa: F811
    model = tmp_path / "model.json"
    # fitted at BASE's --projection-scale 0.5; excess = 1e-5 + 3e-5 - 1e-5 = 3e-5
    save(model, ErrorModel(1e-5, (Component("spherical", 3e-5, 2.0),), 0.5, mean_u2=1e-5))
    argv = [*inputs(pair), "-o", "change.csv", *BASE, "--core-spacing", "0.3", "--lod", "z", "--float64"]
    runs = every_mode(tmp_path / "model", [*argv, "--error-model", str(model)], scheduler, capsys, monkeypatch)
    assert len(runs) >= 4
    plain = every_mode(tmp_path / "plain", argv, scheduler, capsys, monkeypatch)
    a = read_cloud(tmp_path / "plain" / "memory" / "change.csv").fields
    b = read_cloud(tmp_path / "model" / "memory" / "change.csv").fields
    assert plain and np.array_equal(a["distance"], b["distance"], equal_nan=True)
    z = 1.959963984540054
    ok = np.isfinite(a["lod"])
    assert ok.mean() > 0.5
    assert np.allclose(b["lod"][ok], z * np.sqrt((a["lod"][ok] / z) ** 2 + 3e-5), rtol=1e-12)
