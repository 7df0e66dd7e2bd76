"""The run's data-quality warnings (m3c2kit.run.diagnostics) reach every executor and the API: a tiled
run warns exactly as the in-memory run (issue 12: it used to drop them), the API raises them as
M3C2Warning, the command line prints them on stderr, even with -q."""
from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

import m3c2kit
from m3c2kit.cli.main import main
from m3c2kit.base.errors import M3C2Warning
from synthetic import noisy_plane_pair

TORONTO = Path(__file__).resolve().parents[3] / "data" / "toronto-ttp"
# d = 0.05 is far below Toronto's point spacing: the median cylinder is nearly empty.
THIN = ["--core-spacing", "10", "--normal-scale", "2", "--projection-scale", "0.05", "--max-depth", "3"]


def _warnings(capsys, *argv) -> list[str]:
    assert main([str(a) for a in argv]) == 0
    err = capsys.readouterr().err
    return [line for line in err.splitlines() if line.startswith("m3c2: warning: ")]


@pytest.mark.slow
def test_a_tiled_run_gives_the_in_memory_warnings(tmp_path, capsys):
    pair = (TORONTO / "TTP_15.laz", TORONTO / "TTP_23.laz")
    memory = _warnings(capsys, "compare", *pair, "-o", tmp_path / "a.laz", *THIN, "-q")
    tiled = _warnings(capsys, "compare", *pair, "-o", tmp_path / "b.laz", *THIN, "-q", "--tile-size", "5")
    assert any("the median cylinder holds" in line for line in memory)
    # The same warnings, m3c2kit.run.quality's diagnosis of empty cylinders included: a tiled run
    # streams the points of the diagnosed cylinders (m3c2kit.run.cylinder_points).
    assert any("in their cylinder" in line for line in memory)
    assert tiled == memory


def test_the_api_raises_the_warnings_as_m3c2_warnings():
    ref, cmp = noisy_plane_pair(n=40)
    with pytest.warns(M3C2Warning, match="the median cylinder holds"):
        m3c2kit.compare(ref, cmp, normal_scale=0.5, projection_scale=0.01, max_depth=0.5)
    with warnings.catch_warnings():
        warnings.simplefilter("error", M3C2Warning)  # a well-parameterised run does not warn
        r = m3c2kit.compare(ref, cmp, normal_scale=0.5, projection_scale=0.3, max_depth=0.5)
    assert np.isfinite(r.lod).mean() > 0.9


def test_quiet_silences_the_summary_not_the_warnings(tmp_path, capsys):
    ref, cmp = noisy_plane_pair(n=40)
    m3c2kit.io.write_cloud_table(tmp_path / "r.xyz", ref, {})
    m3c2kit.io.write_cloud_table(tmp_path / "c.xyz", cmp, {})
    argv = ["compare", tmp_path / "r.xyz", tmp_path / "c.xyz", "-o", tmp_path / "o.csv", "--normal-scale", "0.5",
            "--projection-scale", "0.01", "--max-depth", "0.5"]
    assert main([str(a) for a in argv + ["-q"]]) == 0
    out, err = capsys.readouterr()
    assert out == "" and "m3c2: warning: the median cylinder holds" in err
    assert main([str(a) for a in argv + ["--verbose"]]) == 0
    out, _ = capsys.readouterr()
    assert "parameter projection_scale: 0.01" in out
