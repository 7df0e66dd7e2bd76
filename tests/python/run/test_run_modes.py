"""Every compare option in every run mode (issue 12's executor; issues 16 and 18): the in-memory
run, tiled runs of several tile sizes and a run on a Dask cluster execute one plan
(m3c2kit.run), and their output files are identical byte for byte, for --uncertainty pm and ep
(the per-point precisions and scan-position ids partitioned with the points, EP's transformation
moving the compared cloud across tile borders), --classifier/--keep (each cloud classified tile by
tile), --float64 and --field-names. A spill write that fails is one clean error, nothing left."""
from __future__ import annotations

import errno
import json
import os
from pathlib import Path

import numpy as np
import pytest

from m3c2kit.cli.main import main
from m3c2kit.io import write_cloud_table

BASE = ["--normal-scale", "1", "--projection-scale", "0.5", "--max-depth", "0.5", "--quiet"]
TILES = ("0.6", "1.7")


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    """A 4 x 4 m rough pair as LAS files with precision extra bytes (sx, sy, sz) and scan-position
    ids (point_source_id), and the EP inputs: two scan positions, a transformation that moves the
    compared cloud by 0.3 m (more than a tile's halo), its covariance and a reduction point."""
    d = tmp_path_factory.mktemp("modes")
    rng = np.random.default_rng(8)
    for name, dz in (("ref", 0.0), ("cmp", 0.02)):
        xy = rng.uniform(0, 4, (4000, 2))
        z = dz + 0.05 * np.sin(xy[:, 0] * 2) + rng.normal(0, 0.003, 4000)
        s = rng.uniform(0.002, 0.01, (4000, 3))
        write_cloud_table(d / f"{name}.las", np.column_stack([xy, z]),
                          {"sx": s[:, 0], "sy": s[:, 1], "sz": s[:, 2],
                           "point_source_id": rng.integers(1, 3, 4000).astype(np.uint16)})
    core = np.column_stack([rng.uniform(0.2, 3.8, (300, 2)), np.full(300, 0.001)])
    write_cloud_table(d / "core.xyz", core, {})
    (d / "sps.json").write_text(json.dumps({
        "1": {"origin": [-10, 2, 2], "sigma_range": 0.003, "sigma_scan": 0.0003, "sigma_yaw": 0.0003},
        "2": {"origin": [12, 1, 3], "sigma_range": 0.004, "sigma_scan": 0.0002, "sigma_yaw": 0.0004}}))
    c, s_ = np.cos(0.01), np.sin(0.01)
    np.savetxt(d / "tfM.csv", [[c, -s_, 0, 0.3], [s_, c, 0, -0.2], [0, 0, 1, 0.01]], delimiter=",")
    np.savetxt(d / "Cxx.csv", np.diag([1e-8] * 9 + [1e-6] * 3), delimiter=",")
    return d


@pytest.fixture(scope="module")
def scheduler():
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, processes=False, threads_per_worker=1, dashboard_address=None,
                                  silence_logs=50) as cluster:
        yield cluster.scheduler_address


def run_every_mode(d: Path, tag: str, inputs: list, flags: list, scheduler: str | None, suffix: str = ".csv") -> bytes:
    """Runs the comparison in memory, tiled at TILES and on Dask; returns the in-memory output after
    checking that every mode wrote the same bytes (the reference's attributes of the core points
    included: m3c2kit.run.attributes)."""
    outputs = {}
    modes = {"memory": []} | {f"tile{s}": ["--tile-size", s] for s in TILES}
    if scheduler is not None:
        modes["dask"] = ["--tile-size", "1.1", "--dask-scheduler", scheduler]
    for mode, extra in modes.items():
        out = d / f"{tag}-{mode}{suffix}"
        assert main(["compare", *inputs, "-o", str(out), *BASE, *flags, *extra]) == 0, mode
        outputs[mode] = out.read_bytes()
    assert not [p for p in d.iterdir() if p.name.startswith(".")], "a spill folder was left"
    expected = outputs["memory"]
    for mode, data in outputs.items():
        if mode != "memory":
            assert data == expected, f"{tag}: {mode} differs from the in-memory run"
    return expected


def header(data: bytes) -> list[str]:
    return data.split(b"\n", 1)[0].decode().split(",")


def columns(data: bytes) -> dict:
    names = header(data)
    rows = np.genfromtxt(data.decode().splitlines()[1:], delimiter=",")
    return {n: rows[:, k] for k, n in enumerate(names)}


def clouds(d):
    return [str(d / "ref.las"), str(d / "cmp.las"), "--core", str(d / "core.xyz")]


@pytest.mark.slow
def test_pm_in_every_mode(pair, scheduler):
    data = run_every_mode(pair, "pm", clouds(pair), ["--uncertainty", "pm", "--precision-scales", "2,0.5"], scheduler)
    cols = columns(data)
    assert "spread1" in cols and np.isfinite(cols["spread1"]).mean() > 0.9  # the fields were read


@pytest.mark.slow
def test_ep_in_every_mode(pair, scheduler):
    flags = ["--uncertainty", "ep", "--scan-positions", str(pair / "sps.json"), "--transform", str(pair / "tfM.csv"),
             "--alignment-covariance", str(pair / "Cxx.csv"), "--reduction-point", "2,2,0"]
    cols = columns(run_every_mode(pair, "ep", clouds(pair), flags, scheduler))
    # The compared cloud moved by 0.3 m onto the core points' tiles: most cylinders found it.
    assert np.isfinite(cols["distance"]).mean() > 0.9 and np.isfinite(cols["spread2"]).mean() > 0.9


@pytest.mark.slow
def test_float64_and_field_names_in_every_mode(pair, scheduler):
    data = run_every_mode(pair, "names", clouds(pair), ["--float64", "--field-names", "cloudcompare"], scheduler)
    names = header(data)
    assert "distance" not in names and len(names) > 10  # CloudCompare's names, not m3c2's
    plain = run_every_mode(pair, "plain", clouds(pair), [], None)
    a, b = columns(data), columns(plain)
    # float64 keeps the engine's doubles: the float32 column is their rounding.
    np.testing.assert_array_equal(np.asarray(list(a.values())[3], np.float32), np.asarray(b["distance"], np.float32))


@pytest.mark.slow
def test_all_fields_in_every_mode(pair, scheduler):
    """LAS/LAZ keeps CloudCompare's columns unless --all-fields (docs/python.md): every mode writes
    the same file either way, and --all-fields adds the spreads, normals and scales."""
    from m3c2kit.io import read_cloud

    compact = run_every_mode(pair, "compact", clouds(pair), [], scheduler, suffix=".laz")
    every = run_every_mode(pair, "every", clouds(pair), ["--all-fields"], scheduler, suffix=".laz")
    assert len(every) > len(compact)
    fields = {name: read_cloud(pair / f"{name}-memory.laz").fields for name in ("compact", "every")}
    assert {"sigma1", "nx", "roughness"} <= set(fields["every"]) and "nx" not in fields["compact"]
    np.testing.assert_array_equal(fields["every"]["distance"], fields["compact"]["distance"])


@pytest.mark.slow
def test_classifier_in_every_mode(tmp_path, scheduler):
    pytest.importorskip("sklearn")
    from canupo_scene import GROUND, VEGETATION, scene
    from m3c2kit.classify import train, write_classifier

    a, la = scene(11, size=8)
    b, lb = scene(11, size=8)
    veg2, lv = scene(12, size=8)
    epoch2 = np.vstack([b[lb == GROUND] + [0, 0, 0.10], veg2[lv == VEGETATION]])  # ground raised, new shrubs
    clf = train([(a[la == GROUND], "2"), (a[la == VEGETATION], "3")], [0.5, 1.0], max_per_class=3000)
    write_classifier(tmp_path / "c.json", clf)
    write_cloud_table(tmp_path / "e1.las", a, {})
    write_cloud_table(tmp_path / "e2.las", epoch2, {})
    flags = ["--classifier", str(tmp_path / "c.json"), "--keep", "2"]
    inputs = [str(tmp_path / "e1.las"), str(tmp_path / "e2.las")]
    # Core points: the kept reference points subsampled (the core points depend on the filter).
    cols = columns(run_every_mode(tmp_path, "veg", inputs, flags + ["--core-spacing", "0.5"], scheduler))
    ok = np.isfinite(cols["distance"])
    assert ok.mean() > 0.8 and abs(np.median(cols["distance"][ok]) - 0.10) < 0.01


def test_a_full_disk_during_the_spill_is_one_clean_error(pair, monkeypatch, capsys):
    from m3c2kit.run import spill

    real = np.ndarray.tofile

    def full(self, f, *args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(spill, "_tofile", full)
    out = pair / "full.csv"
    assert main(["compare", *clouds(pair), "-o", str(out), *BASE, "--tile-size", "1"]) == 1
    err = capsys.readouterr().err
    assert err == (f"m3c2: error: {pair}: cannot write the tiled run's spill files (kept in a work folder there "
                   f"until the run ends): {os.strerror(errno.ENOSPC)}\n")
    assert not out.exists() and not [p for p in pair.iterdir() if p.name.startswith(".")]
    assert real is np.ndarray.tofile
