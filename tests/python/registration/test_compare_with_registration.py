"""m3c2 compare with m3c2 register's T.json (docs/registration.md): --transform moves the compared
cloud before comparing, --registration-error takes its registration_error, M3C2-EP's
--alignment-covariance its covariance through the Jacobian at the estimate."""
from __future__ import annotations

import json

import numpy as np
import pytest

from m3c2kit.cli.main import main
from m3c2kit.io.registration_file import Registration, read_registration, registration_bytes
from m3c2kit.run import registration_inputs

from terrain import epochs, rotation
from test_register import run  # the command line's (code, stdout, stderr)

SCALES = ["--normal-scale", "0.6", "--projection-scale", "0.5", "--max-depth", "1", "-q"]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("compare_registration")
    reference, compared = epochs(6_000, seed=5)
    np.save(folder / "ref.npy", reference)
    np.save(folder / "cmp.npy", compared)
    assert main([str(a) for a in ("register", folder / "ref.npy", folder / "cmp.npy", "-o", folder / "t.json",
                                  "--normal-scale", "0.6", "-q")]) == 0
    reg = read_registration(folder / "t.json", "-o")
    np.save(folder / "moved.npy", reg.moved(compared))
    return folder


def _table(path):
    return np.genfromtxt(path, delimiter=",", names=True)


def test_transform_equals_comparing_the_moved_cloud(files, capsys):
    a, b = files / "a.csv", files / "b.csv"
    assert run(capsys, "compare", files / "ref.npy", files / "cmp.npy", "-o", a, "--transform", files / "t.json",
               *SCALES)[0] == 0
    assert run(capsys, "compare", files / "ref.npy", files / "moved.npy", "-o", b, *SCALES)[0] == 0
    ta, tb = _table(a), _table(b)
    for name in ("distance", "lod", "n1", "n2"):
        np.testing.assert_array_equal(ta[name], tb[name])


def test_registration_error_from_the_file_equals_the_number(files, capsys):
    reg = read_registration(files / "t.json", "-o")
    a, b = files / "ra.csv", files / "rb.csv"
    assert run(capsys, "compare", files / "ref.npy", files / "moved.npy", "-o", a, "--registration-error",
               files / "t.json", *SCALES)[0] == 0
    assert run(capsys, "compare", files / "ref.npy", files / "moved.npy", "-o", b, "--registration-error",
               repr(reg.registration_error), *SCALES)[0] == 0
    np.testing.assert_array_equal(_table(a)["lod"], _table(b)["lod"])
    assert reg.registration_error > 0


@pytest.mark.parametrize("option", ["--transform", "--registration-error"])
def test_a_json_that_is_not_a_registration_is_refused(files, tmp_path, capsys, option):
    other = tmp_path / "model.json"
    other.write_text(json.dumps({"nugget": 1.0}))
    code, _, err = run(capsys, "compare", files / "ref.npy", files / "cmp.npy", "-o", tmp_path / "o.csv", option,
                       other, *SCALES)
    assert code == 2 and "not a registration file" in err and str(other) in err and "Traceback" not in err, err
    assert not (tmp_path / "o.csv").exists()


def test_a_tiled_run_moves_the_compared_cloud_as_it_streams(files, tmp_path, capsys):
    """The tiles hold the compared points moved as they are read (run/registration_inputs.MovedSource):
    the output is the in-memory run's, byte for byte."""
    whole, tiled = tmp_path / "whole.csv", tmp_path / "tiled.csv"
    common = ("--transform", files / "t.json", *SCALES)
    assert run(capsys, "compare", files / "ref.npy", files / "cmp.npy", "-o", whole, *common)[0] == 0
    code, _, err = run(capsys, "compare", files / "ref.npy", files / "cmp.npy", "-o", tiled, "--tile-size", "2",
                       *common)
    assert code == 0, err
    assert tiled.read_bytes() == whole.read_bytes()


def _ep_parameters(reg: Registration, delta: np.ndarray, red: np.ndarray) -> np.ndarray:
    """EP's (r11..r33, t at red) of the estimate perturbed by delta = (w, s) as the covariance means:
    p' = exp([w]x) (M p - c) + c + s."""
    turn = rotation(delta[:3]) if np.any(delta[:3]) else np.eye(3)
    c, m = reg.centre, reg.matrix
    r = turn @ m[:3, :3]
    moved_red = turn @ (m[:3, :3] @ red + m[:3, 3] - c) + c + delta[3:]
    return np.concatenate([r.reshape(9), moved_red - red])


def test_ep_alignment_covariance_is_the_jacobian_at_the_estimate(files):
    reg = read_registration(files / "t.json", "-o")
    red = np.array([3.0, -2.0, 1.5])
    step = 1e-6
    numeric = np.column_stack([(_ep_parameters(reg, step * e, red) - _ep_parameters(reg, -step * e, red)) / (2 * step)
                               for e in np.eye(6)])
    np.testing.assert_allclose(registration_inputs.ep_jacobian(reg, red), numeric, atol=1e-8)
    c12 = registration_inputs.ep_alignment_covariance(reg, red)
    np.testing.assert_allclose(c12, numeric @ reg.covariance @ numeric.T, rtol=1e-6, atol=1e-20)
    assert np.array_equal(c12, c12.T)
    # EP's transform about red is the file's motion
    t = registration_inputs.ep_transform(reg, red)
    p = np.array([[1.0, 2.0, 3.0], [10.0, -4.0, 0.5]])
    np.testing.assert_allclose((p - red) @ t[:, :3].T + t[:, 3] + red, reg.moved(p), atol=1e-12)


def test_registration_file_round_trips(tmp_path):
    reg = Registration(np.eye(4), np.eye(6) * 1e-8, np.array([1.0, 2.0, 3.0]), 0.004, {"pairs": 10})
    path = tmp_path / "t.json"
    path.write_bytes(registration_bytes(reg))
    back = read_registration(path, "--transform")
    assert np.array_equal(back.matrix, reg.matrix) and back.registration_error == 0.004
