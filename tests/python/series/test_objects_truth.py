"""4D objects-by-change against a known truth (validation/objects_scenes.py: core points on a grid,
distances stored directly, five events above 6 mm of noise, two seeds): the default `--dtw
baseline` finds every event with an object of IoU >= 0.5 in space and time, raw and smoothed,
and nothing on noise alone; the rule before it (seed-start) misses the rockfall's step, so these
assertions can fail. Each rule's DTW values equal a brute-force O(n^2) DTW with the rule's offsets
and D_max. C++: tests/cpp/test_objects_truth.cpp."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(REPO / "validation"))

from m3c2kit import _core  # noqa: E402
from m3c2kit.series import engine  # noqa: E402
import objects_scenes as sc  # noqa: E402


def found(out: dict, n_core: int) -> list[np.ndarray]:
    o = out["member_offsets"]
    return [sc.extent(n_core, out["members"][o[k]:o[k + 1]], out["object_start"][k], out["object_end"][k])
            for k in range(len(o) - 1)]


def run(d, core, rule="baseline", smoothed=False):
    values = engine.temporal_median(d, 5) if smoothed else d
    return engine.objects_by_change(values, core, engine.objects_params(dtw=rule))


@pytest.mark.parametrize("seed", [1, 2])
@pytest.mark.parametrize("smoothed", [False, True])
def test_the_default_finds_every_event_and_nothing_else(seed, smoothed):
    core, d = sc.scene(seed)
    s = sc.score(found(run(d, core, smoothed=smoothed), len(core)), core)
    assert all(v >= 0.5 for v in s["best"].values()), s["best"]
    assert s["precision"] == 1.0 and s["false"] == 0, s


@pytest.mark.parametrize("rule", ["baseline", "seed-start", "py4dgeo"])
def test_nothing_on_noise(rule):
    for seed in (1, 2):
        core, d = sc.scene(seed, events=False)
        for smoothed in (False, True):
            assert len(run(d, core, rule, smoothed)["object_seed"]) == 0


def test_the_seed_start_rule_misses_the_step():
    """Measured from the seed's first epoch, already the new level after a step, the rockfall's
    volume is noise: no seed, no object. The reason for the baseline (docs/series.md)."""
    for seed in (1, 2):
        core, d = sc.scene(seed)
        assert sc.score(found(run(d, core, "seed-start"), len(core)), core)["best"]["rockfall"] < 0.5


def brute_dtw(x, y):
    n = len(x)
    D = np.full((n + 1, n + 1), np.inf)
    D[0, 0] = 0.0
    for i in range(n):
        for j in range(n):
            D[i + 1, j + 1] = abs(x[i] - y[j]) + min(D[i, j + 1], D[i + 1, j], D[i, j])
    return D[n, n]


@pytest.mark.parametrize("rule", ["baseline", "seed-start", "py4dgeo"])
def test_each_rules_dtw_is_the_brute_force_one(rule):
    core, d = sc.scene(3)
    out = run(d, core, rule, smoothed=rule == "seed-start")  # (seed-start finds nothing on the raw scene)
    if rule == "seed-start":
        d = engine.temporal_median(d, 5)
    o = out["member_offsets"]
    assert len(o) > 1
    for k in range(len(o) - 1):
        c, t0, t1, base = (int(out[f"object_{n}"][k]) for n in ("seed", "start", "end", "base"))

        def offset(row):
            return {"py4dgeo": row[0], "seed-start": row[t0], "baseline": np.median(row[base:t0 + 1])}[rule]

        a = d[c, t0:t1 + 1]
        dmax = np.abs(a).sum() if rule == "py4dgeo" else np.abs(a - offset(d[c])).sum()
        for m, got in list(zip(out["members"][o[k]:o[k + 1]], out["member_dtw"][o[k]:o[k + 1]]))[:15]:
            want = min(1.0, brute_dtw(a - offset(d[c]), d[m, t0:t1 + 1] - offset(d[m])) / dmax)
            assert got == pytest.approx(want, rel=1e-12, abs=1e-15)


def test_the_command_line_names_the_rules():
    from m3c2kit.cli.series import objects_parser, objects_params
    for name, value in (("baseline", _core.ObjectsDtw.baseline), ("seed-start", _core.ObjectsDtw.seed_start),
                        ("py4dgeo", _core.ObjectsDtw.py4dgeo)):
        args = objects_parser().parse_args(["st.zarr", "-o", "o.csv", "--dtw", name])
        assert objects_params(args).dtw == value
    assert objects_params(objects_parser().parse_args(["st.zarr", "-o", "o.csv"])).dtw == _core.ObjectsDtw.baseline
    with pytest.raises(Exception, match="--whole-series"):  # gone: it claimed py4dgeo's rule, and was not it
        objects_parser().parse_args(["st.zarr", "-o", "o.csv", "--whole-series"])


def test_py4dgeo_rule_reads_the_interpolated_epochs():
    """py4dgeo's seed search interpolates each searched series' NaN epochs (np.interp) in place in
    its own array, so its scores and growth read them: --dtw py4dgeo on a series with gaps equals
    it on the series filled by np.interp beforehand, bit for bit."""
    core, d = sc.scene(1)
    d[np.random.default_rng(7).random(d.shape) < 0.05] = np.nan
    filled = d.copy()
    for row in filled:
        bad = np.isnan(row)
        row[bad] = np.interp(np.flatnonzero(bad), np.flatnonzero(~bad), row[~bad])
    a, b = run(d, core, "py4dgeo"), run(filled, core, "py4dgeo")
    assert len(a["object_seed"]) >= 3
    assert all(np.asarray(a[k]).tobytes() == np.asarray(b[k]).tobytes() for k in a)


def test_a_change_still_going_on_at_the_last_epoch_meets_the_height_threshold_too():
    """Hostile round 2: an unfinished seed (the change still going on at the last epoch) was kept
    whatever --height-threshold said (1 m kept a 5 cm rise). py4dgeo's rule keeps it, as py4dgeo."""
    n, cores = 40, 3
    d = np.zeros((cores, n))
    d[:, 10:26] = np.linspace(0.0, 0.05, 16)
    d[:, 26:] = 0.05  # held to the last epoch
    d += np.random.default_rng(0).normal(0, 0.001, d.shape)
    core = np.column_stack([np.arange(cores) * 0.5, np.zeros(cores), np.zeros(cores)])

    def seeds(rule, threshold):
        p = engine.objects_params(window_width=8, window_min_size=4, window_penalty=0.01, min_period=5,
                                  height_threshold=threshold,
                                  use_unfinished=True, dtw=rule, min_segments=1)
        return len(engine.objects_by_change(d, core, p)["object_start"])

    assert seeds("baseline", 0.0) >= 1
    assert seeds("baseline", 1.0) == 0
    assert seeds("py4dgeo", 1.0) == seeds("py4dgeo", 0.0) >= 1


@pytest.mark.parametrize("extra, words", [
    (["--max-cv", "nan"], "--max-cv must be finite and > 0"),
    (["--max-cv", "0"], "--max-cv must be finite and > 0"),
    (["--height-threshold", "nan"], "--height-threshold must be finite and >= 0"),
    (["--height-threshold", "-1"], "--height-threshold must be finite and >= 0"),
    (["--max-segments", "1", "--min-segments", "5"], "--max-segments 1 is below --min-segments 5"),
    (["--window-min-size", "100", "--window-width", "8"], "--window-min-size 100 exceeds --window-width 8"),
])
def test_impossible_objects_options_are_refused(tmp_path, capsys, extra, words):
    """Hostile round 2: each ran with exit 0 and no object, or with objects a contradiction allowed."""
    from m3c2kit.cli.main import main
    assert main(["series", "objects", str(tmp_path / "s.zarr"), "-o", str(tmp_path / "o.csv"), *extra]) == 2
    err = capsys.readouterr().err
    assert words in err and err.count("\n") == 1, err
