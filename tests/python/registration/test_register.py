"""m3c2 register / m3c2kit.register (docs/registration.md): known motions recovered on a rough
terrain with 20 % of its area changed, with --auto-stable and with --stable polygons; a plane
refused; the file's contract; hostile inputs each a clean error."""
from __future__ import annotations

import json
import os

import numpy as np
import pytest

import m3c2kit
from m3c2kit.cli.main import main
from m3c2kit.io.registration_file import read_registration

from terrain import STABLE_GEOJSON, epochs, errors

ROTATION_LIMIT_DEGREES = 0.001
TRANSLATION_LIMIT = 0.001  # 1 mm


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("register")
    reference, compared = epochs(40_000, seed=3, noise=0.002)
    np.save(folder / "ref.npy", reference)
    np.save(folder / "cmp.npy", compared)
    (folder / "stable.geojson").write_text(json.dumps(STABLE_GEOJSON))
    return folder


def test_auto_stable_recovers_the_motion(files, capsys):
    out = files / "auto.json"
    code, stdout, err = run(capsys, "register", files / "ref.npy", files / "cmp.npy", "-o", out, "--auto-stable")
    assert code == 0, err
    reg = read_registration(out, "-o")
    rotation, translation = errors(reg.matrix)
    assert rotation <= ROTATION_LIMIT_DEGREES and translation <= TRANSLATION_LIMIT, (rotation, translation)
    # the 20 % changed is left out, little else
    assert 0.7 <= reg.details["stable_fraction"] <= 0.82, reg.details
    assert "wrote" in stdout


def test_stable_polygons_recover_the_motion(files, capsys):
    out = files / "given.json"
    code, _, err = run(capsys, "register", files / "ref.npy", files / "cmp.npy", "-o", out, "--stable",
                       files / "stable.geojson", "--normal-scale", "0.5", "-q")
    assert code == 0, err
    reg = read_registration(out, "-o")
    rotation, translation = errors(reg.matrix)
    assert rotation <= ROTATION_LIMIT_DEGREES and translation <= TRANSLATION_LIMIT, (rotation, translation)
    assert reg.details["stable"] == "given"


def test_file_contract(files, capsys):
    out = files / "contract.json"
    assert run(capsys, "register", files / "ref.npy", files / "cmp.npy", "-o", out, "--normal-scale", "0.5",
               "-q")[0] == 0
    doc = json.loads(out.read_text())
    assert np.array(doc["matrix"]).shape == (4, 4) and doc["matrix"][3] == [0.0, 0.0, 0.0, 1.0]
    cov = np.array(doc["covariance"])
    assert cov.shape == (6, 6) and np.array_equal(cov, cov.T) and np.all(np.linalg.eigvalsh(cov) > 0)
    assert doc["covariance_parameters"] == ["rx", "ry", "rz", "tx", "ty", "tz"]
    # registration_error: sqrt(sum r^2 / (pairs - 6)); the noise is 3 mm on each cloud
    assert doc["registration_error"] == pytest.approx(doc["rms"] * np.sqrt(doc["pairs"] / (doc["pairs"] - 6)))
    for key in ("iterations", "pairs", "stable_fraction", "rms", "converged", "centre"):
        assert key in doc


def test_api_matches_the_command_line(files):
    reference, compared = np.load(files / "ref.npy"), np.load(files / "cmp.npy")
    reg = m3c2kit.register(reference, compared, normal_scale=0.5, threads=1)
    again = m3c2kit.register(reference, compared, normal_scale=0.5, threads=2)
    assert np.array_equal(reg.matrix, again.matrix) and np.array_equal(reg.covariance, again.covariance)


def test_a_plane_is_refused_with_a_clear_message(tmp_path, capsys):
    rng = np.random.default_rng(1)
    xy = rng.uniform(0, 10, (20_000, 2))
    np.save(tmp_path / "a.npy", np.column_stack([xy, rng.normal(0, 0.002, len(xy))]))
    np.save(tmp_path / "b.npy", np.column_stack([xy + 0.05, rng.normal(0, 0.002, len(xy))]))
    code, _, err = run(capsys, "register", tmp_path / "a.npy", tmp_path / "b.npy", "-o", tmp_path / "t.json",
                       "--normal-scale", "0.5")
    assert code == 2 and "unobservable" in err and "translation along" in err and "Traceback" not in err, err
    assert not (tmp_path / "t.json").exists()


@pytest.mark.parametrize("case", ["empty", "nan", "fifo_output", "fifo_input", "output_is_input", "not_json",
                                  "rounds_without_auto"])
def test_hostile_inputs_are_clean_errors(files, tmp_path, capsys, case):
    ref, cmp_, out = files / "ref.npy", files / "cmp.npy", tmp_path / "t.json"
    extra = ["--normal-scale", "0.5"]
    if case == "empty":
        cmp_ = tmp_path / "empty.npy"
        np.save(cmp_, np.zeros((0, 3)))
    elif case == "nan":
        bad = np.load(files / "cmp.npy")
        bad[5, 2] = np.nan
        cmp_ = tmp_path / "nan.npy"
        np.save(cmp_, bad)
    elif case == "fifo_output":
        out = tmp_path / "fifo.json"
        os.mkfifo(out)
    elif case == "fifo_input":
        cmp_ = tmp_path / "fifo.npy"
        os.mkfifo(cmp_)
    elif case == "output_is_input":
        out = tmp_path / "same.json"
        out.write_text("{}")
        extra += ["--stable", out]
    elif case == "not_json":
        out = tmp_path / "t.las"
    elif case == "rounds_without_auto":
        extra += ["--rounds", "3"]
    code, _, err = run(capsys, "register", ref, cmp_, "-o", out, *extra)
    assert code in (1, 2) and err.strip() and "Traceback" not in err, err
    assert len(err.strip().splitlines()) == 1, err
    if case not in ("fifo_output", "output_is_input"):
        assert not out.exists()


@pytest.mark.slow
def test_a_million_points(tmp_path):
    reference, compared = epochs(1_000_000, seed=8)
    reg = m3c2kit.register(reference, compared, auto_stable=True)
    rotation, translation = errors(reg.matrix)
    assert rotation <= ROTATION_LIMIT_DEGREES and translation <= TRANSLATION_LIMIT, (rotation, translation)
