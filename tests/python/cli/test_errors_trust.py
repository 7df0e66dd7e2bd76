"""docs/errors.md, "No special file hangs, and clean errors everywhere" (issue 31, items 4 and 6).

Every file option refuses a FIFO (it would block), /dev/zero (it never ends) and a directory with
one line naming the file, before any output; names over 255 bytes, overflowing lengths, forged
classifier and scan-position files, wrong API argument types and degenerate inputs each give one
clean line (or the package's own exception), never a traceback, binding text or numpy warning.
The command line runs in this process (fast); an alarm turns a hang into a failure."""
from __future__ import annotations

import errno
import json
import os
import signal
import socket
import stat
import warnings
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

import m3c2kit
from m3c2kit import engine
from m3c2kit.classify.model import ClassifierFileError, read_classifier
from m3c2kit.cli.main import main
from m3c2kit.base.errors import UsageError
from m3c2kit.io import write_cloud_table
from m3c2kit.io.input_file import SMALL_FILE_LIMITS, read_small_bytes
from m3c2kit.run.uncertainty_inputs import load_scan_positions

pytestmark = pytest.mark.skipif(not hasattr(os, "mkfifo") or not os.path.exists("/dev/zero"),
                                reason="needs FIFOs and /dev/zero")

SCALES = ["--normal-scale", "1", "--projection-scale", "1", "--max-depth", "1"]
LONG = "n" * 300  # one path component over NAME_MAX (255 bytes)


@contextmanager
def no_hang(seconds: int = 20):
    """A blocking open or an endless read fails the test instead of hanging it."""
    def expire(signum, frame):
        raise TimeoutError(f"still running after {seconds} s: it blocked")
    previous = signal.signal(signal.SIGALRM, expire)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def run(argv, capsys) -> tuple[int, str]:
    with no_hang():
        code = main([str(a) for a in argv])
    return code, capsys.readouterr().err


def one_line(err: str) -> str:
    assert err.count("\n") == 1 and err.startswith("m3c2: error: "), err
    assert "Traceback" not in err
    return err[len("m3c2: error: "):-1]


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("trust")
    rng = np.random.default_rng(7)
    for name in ("a", "b"):
        write_cloud_table(folder / f"{name}.ply", rng.random((60, 3)),
                          {"point_source_id": np.ones(60, np.uint16)})
        np.savetxt(folder / f"{name}.xyz", rng.random((60, 3)))
    (folder / "sp.csv").write_text("id,x,y,z,sigma_range,sigma_scan,sigma_yaw\n1,0,0,5,0.01,0.001,0.001\n")
    (folder / "tf.txt").write_text("1 0 0 0\n0 1 0 0\n0 0 1 0\n")
    # A compare output and the files of the newest commands (issue 42): regions, an error model.
    xy = rng.random((60, 2)) * 10
    ones = np.ones(60)
    write_cloud_table(folder / "result.csv", np.column_stack([xy, np.zeros(60)]),
                      {"distance": rng.normal(0, 0.01, 60), "lod": 0.03 * ones, "sigma1": 0.01 * ones,
                       "sigma2": 0.01 * ones, "n1": 20 * ones, "n2": 20 * ones, "significant": np.zeros(60)})
    (folder / "regions.geojson").write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"name": "r"},
         "geometry": {"type": "Polygon", "coordinates": [[[0, 0], [10, 0], [10, 10], [0, 10], [0, 0]]]}}]}))
    (folder / "model.json").write_text(json.dumps({
        "format": "m3c2kit-error-model", "version": 2, "nugget": 1e-5, "lag_distance": "3d", "projection_scale": 1.0,
        "mean_u2": 1e-5, "components": [{"kind": "spherical", "sill": 1e-5, "range": 3.0}]}))
    return folder


def special(tmp_path: Path, kind: str, suffix: str) -> Path:
    """A FIFO, a link to /dev/zero, a Unix socket or a directory, named with the option's extension."""
    path = tmp_path / f"special{suffix}"
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "socket":  # bound by a relative name: a socket's path is limited to 108 bytes
        server = socket.socket(socket.AF_UNIX)
        cwd = os.getcwd()
        os.chdir(tmp_path)
        try:
            server.bind(path.name)
        finally:
            os.chdir(cwd)
        server.close()  # the socket file stays
    elif kind == "zero":
        path.symlink_to("/dev/zero")
    else:
        path.mkdir()
    return path


EP = ["--uncertainty", "ep", *SCALES]
#: option: (extension, exit code, argv given the data folder D, the output O and the special file P)
OPTIONS = {
    "compare reference": (".xyz", 1, lambda D, O, P: ["compare", P, D / "b.xyz", "-o", O, *SCALES]),
    "compare --core": (".xyz", 1, lambda D, O, P: ["compare", D / "a.xyz", D / "b.xyz", "--core", P, "-o", O, *SCALES]),
    "compare --core-normals": (".xyz", 1, lambda D, O, P: [
        "compare", D / "a.xyz", D / "b.xyz", "--core", D / "a.xyz", "--normal-source", "core", "--core-normals", P,
        "-o", O, "--projection-scale", "1", "--max-depth", "1"]),
    "compare --orient FILE": (".xyz", 1, lambda D, O, P: ["compare", D / "a.xyz", D / "b.xyz", "--orient", P, "-o", O,
                                                          *SCALES]),
    "compare --params": (".txt", 2, lambda D, O, P: ["compare", D / "a.xyz", D / "b.xyz", "--params", P, "-o", O,
                                                     *SCALES]),
    "compare --crs": (".prj", 2, lambda D, O, P: ["compare", D / "a.xyz", D / "b.xyz", "--crs", P, "-o", O, *SCALES]),
    "compare --scan-positions": (".json", 2, lambda D, O, P: ["compare", D / "a.ply", D / "b.ply", "-o", O, *EP,
                                                              "--scan-positions", P]),
    "compare --transform": (".txt", 2, lambda D, O, P: ["compare", D / "a.ply", D / "b.ply", "-o", O, *EP,
                                                        "--scan-positions", D / "sp.csv", "--transform", P]),
    "compare --reduction-point": (".csv", 2, lambda D, O, P: [
        "compare", D / "a.ply", D / "b.ply", "-o", O, *EP, "--scan-positions", D / "sp.csv", "--transform",
        D / "tf.txt", "--reduction-point", P]),
    "compare --alignment-covariance": (".txt", 2, lambda D, O, P: [
        "compare", D / "a.ply", D / "b.ply", "-o", O, *EP, "--scan-positions", D / "sp.csv",
        "--alignment-covariance", P]),
    "compare --classifier": (".json", 1, lambda D, O, P: ["compare", D / "a.xyz", D / "b.xyz", "-o", O, *SCALES,
                                                          "--classifier", P, "--keep", "1"]),
    "series --core-normals": (".xyz", 1, lambda D, O, P: [
        "series", D / "a.xyz", D / "b.xyz", "-o", O.with_suffix(".zarr"), "--normal-source", "core", "--core-normals", P,
        "--projection-scale", "1", "--max-depth", "1"]),
    "normals input": (".xyz", 1, lambda D, O, P: ["normals", P, "-o", O, "--normal-scale", "1"]),
    "c2c compared": (".xyz", 1, lambda D, O, P: ["c2c", D / "a.xyz", P, "-o", O]),
    "calibrate cloud": (".xyz", 1, lambda D, O, P: ["calibrate", P, "--projection-scales", "0.5,1", "-o", O]),
    "classify apply --classifier (JSON)": (".json", 1, lambda D, O, P: ["classify", "apply", D / "a.xyz",
                                                                        "--classifier", P, "-o", O]),
    "classify apply --classifier (.prm)": (".prm", 1, lambda D, O, P: ["classify", "apply", D / "a.xyz",
                                                                       "--classifier", P, "-o", O]),
    "classify train --polygons": (".geojson", 2, lambda D, O, P: ["classify", "train", D / "a.xyz", "--polygons", P,
                                                                  "-o", O]),
    "info": (".xyz", 1, lambda D, O, P: ["info", P]),
    # The newest commands (issue 42).
    "convert input": (".xyz", 1, lambda D, O, P: ["convert", P, "-o", O]),
    "variogram result": (".csv", 1, lambda D, O, P: ["variogram", P, "-o", O.with_suffix(".json")]),
    "variogram --stable": (".geojson", 2, lambda D, O, P: ["variogram", D / "result.csv", "--stable", P, "-o",
                                                           O.with_suffix(".json")]),
    "aggregate result": (".csv", 1, lambda D, O, P: ["aggregate", P, "--regions", D / "regions.geojson", "-o", O]),
    "aggregate --regions": (".geojson", 2, lambda D, O, P: ["aggregate", D / "result.csv", "--regions", P, "-o", O]),
    "aggregate --error-model": (".json", 2, lambda D, O, P: ["aggregate", D / "result.csv", "--regions",
                                                             D / "regions.geojson", "--error-model", P, "-o", O]),
    "compare --error-model": (".json", 2, lambda D, O, P: ["compare", D / "a.xyz", D / "b.xyz", "-o", O, *SCALES,
                                                           "--error-model", P]),
    # m3c2 register and its file in compare (issue 43)
    "register reference": (".xyz", 1, lambda D, O, P: ["register", P, D / "b.xyz", "-o", O.with_suffix(".json"),
                                                       "--normal-scale", "1"]),
    "register compared": (".xyz", 1, lambda D, O, P: ["register", D / "a.xyz", P, "-o", O.with_suffix(".json"),
                                                      "--normal-scale", "1"]),
    "register --stable": (".geojson", 2, lambda D, O, P: ["register", D / "a.xyz", D / "b.xyz", "--stable", P, "-o",
                                                          O.with_suffix(".json"), "--normal-scale", "1"]),
    "compare --transform (T.json)": (".json", 2, lambda D, O, P: ["compare", D / "a.xyz", D / "b.xyz", "-o", O,
                                                                  *SCALES, "--transform", P]),
    "compare --registration-error (T.json)": (".json", 2, lambda D, O, P: [
        "compare", D / "a.xyz", D / "b.xyz", "-o", O, *SCALES, "--registration-error", P]),
}


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["fifo", "zero", "socket", "directory"])
@pytest.mark.parametrize("option", sorted(OPTIONS))
def test_every_file_option_refuses_special_files(option, kind, data, tmp_path, capsys):
    suffix, expected_code, argv = OPTIONS[option]
    path = special(tmp_path, kind, suffix)
    out = tmp_path / ("out.json" if "train" in option else "out.csv")
    code, err = run(argv(data, out, path), capsys)
    message = one_line(err)
    problem = "is a directory" if kind == "directory" else "not a regular file"
    assert f"{path}: {problem}" in message
    assert code == expected_code
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]  # no output, no temporary


def test_small_files_are_read_up_to_their_kind_limit(tmp_path, monkeypatch):
    monkeypatch.setitem(SMALL_FILE_LIMITS, "matrix file", 8)
    (tmp_path / "ok.txt").write_bytes(b"12345678")
    assert read_small_bytes(tmp_path / "ok.txt", "matrix file") == b"12345678"
    (tmp_path / "big.txt").write_bytes(b"123456789")
    with pytest.raises(UsageError, match=r"big\.txt: larger than 8 bytes; too large for a matrix file$"):
        read_small_bytes(tmp_path / "big.txt", "matrix file")
    with open(tmp_path / "sparse.txt", "wb") as f:  # 64 GiB that take no disk: read whole, they fill the memory
        f.truncate(1 << 36)
    with pytest.raises(UsageError, match="too large for a matrix file"):
        read_small_bytes(tmp_path / "sparse.txt", "matrix file")


# ------------------------------------------------------------------- names over 255 bytes

@pytest.mark.parametrize("where", ["reference", "output", "output folder", "classifier", "params", "orient"])
def test_a_name_over_255_bytes_is_one_clean_line(where, data, tmp_path, capsys):
    long_path = tmp_path / (LONG + ".xyz")
    out = tmp_path / "out.csv"
    argv = {
        "reference": ["compare", long_path, data / "b.xyz", "-o", out, *SCALES],
        "output": ["compare", data / "a.xyz", data / "b.xyz", "-o", tmp_path / (LONG + ".csv"), *SCALES],
        "output folder": ["compare", data / "a.xyz", data / "b.xyz", "-o", tmp_path / LONG / "o.csv", *SCALES],
        "classifier": ["classify", "apply", data / "a.xyz", "--classifier", tmp_path / (LONG + ".json"), "-o", out],
        "params": ["compare", data / "a.xyz", data / "b.xyz", "--params", tmp_path / LONG, "-o", out, *SCALES],
        "orient": ["compare", data / "a.xyz", data / "b.xyz", "--orient", LONG, "-o", out, *SCALES],
    }[where]
    code, err = run(argv, capsys)
    message = one_line(err)
    assert code == (2 if where in ("params", "orient") else 1)
    if where != "orient":  # --orient: a name that cannot exist is no file: the usage of --orient
        assert "file name too long" in message
    assert list(tmp_path.iterdir()) == []


def test_an_output_name_over_255_bytes_is_refused_before_the_run(data, tmp_path, capsys):
    code, err = run(["compare", data / "a.xyz", data / "b.xyz", "-o", tmp_path / (LONG + ".csv"), *SCALES], capsys)
    assert code == 1 and "warning" not in err  # no diagnostics: the run never started


@pytest.mark.parametrize("number, strerror, words", [
    (errno.ENAMETOOLONG, "File name too long", "file name too long (a path component over 255 bytes"),
    (errno.ENOSPC, "No space left on device", "No space left on device"),
    (errno.EDQUOT, "Disk quota exceeded", "Disk quota exceeded"),
])
def test_an_os_error_no_reader_converted_is_one_line_naming_its_file(number, strerror, words, data, tmp_path,
                                                                      capsys, monkeypatch):
    # The command line's net for OS errors raised where no reader or writer names the file
    # (pathlib's checks raise ENAMETOOLONG instead of answering; a full disk in any command).
    def fail(*args, **kwargs):
        raise OSError(number, strerror, str(tmp_path / "out.csv"))
    monkeypatch.setattr("m3c2kit.cli.compare.check_outputs", fail)
    code, err = run(["compare", data / "a.xyz", data / "b.xyz", "-o", tmp_path / "out.csv", *SCALES], capsys)
    message = one_line(err)
    assert code == 1 and message.startswith(f"{tmp_path / 'out.csv'}: {words}")


# -------------------------------------------------------------------- overflowing lengths

@pytest.mark.parametrize("options, words", [
    (["--normal-scale", "1e300", "--projection-scale", "1", "--max-depth", "1", "--tile-size", "5"],
     "--tile-size 5 is too small for the halo"),
    (["--normal-scale", "1e308", "--projection-scale", "1e308", "--max-depth", "1e308", "--tile-size", "1e308"],
     "exceeds the largest float"),
    (["--normal-scale", "1e308", "--projection-scale", "1", "--max-depth", "1e308", "--memory-limit", "1G"],
     "exceeds the largest float"),
    (["--normal-scale", "1:1e300:1e-300", "--projection-scale", "1", "--max-depth", "1"], "too many scales"),
])
def test_overflowing_lengths_are_usage_errors(options, words, data, tmp_path, capsys):
    code, err = run(["compare", data / "a.xyz", data / "b.xyz", "-o", tmp_path / "o.csv", *options], capsys)
    assert words in one_line(err)
    assert code == 2


@pytest.mark.parametrize("argv, words", [
    (["c2c", "A", "B", "-o", "O", "--model", "plane", "--model-knn", "4000000000000000000"],
     "argument --model-knn: must be an integer from"),
    (["roughness", "A", "--normal-scale", "1", "-o", "O", "--min-points", "99999999999999999999"],
     "argument --min-points: must be an integer from"),
    (["suggest", "A", "B", "--seed", "-1"], "argument --seed: must be an integer from"),
    # The parameter table's --threads, in every command (cli/options.py): the table's range and words.
    (["c2c", "A", "B", "-o", "O", "--threads", "4294967296"],
     "--threads must be 0 (all) or a positive integer, at most 2147483647"),
])
def test_integer_options_beyond_the_engine_are_usage_errors(argv, words, data, tmp_path, capsys):
    names = {"A": data / "a.xyz", "B": data / "b.xyz", "O": tmp_path / "o.csv"}
    code, err = run([names.get(a, a) for a in argv], capsys)
    assert code == 2 and words in err
    assert "incompatible function arguments" not in err and "Traceback" not in err


# ------------------------------------------------------------------- forged classifiers

def _classifier() -> dict:
    return {"format": "m3c2kit-canupo-classifier", "version": 1, "scales": [1.0], "min_points": 3,
            "labels": ["1", "2"], "classifiers": [{"class1": "1", "class2": "2", "w1": [1.0, 0.0, 0.0],
                                                   "w2": [0.0, 1.0, 0.0], "path": [[0, -1], [0, 1]],
                                                   "ref_pos": [1, 0], "ref_neg": [-1, 0]}]}


def _forge(change):
    d = _classifier()
    change(d)
    return json.dumps(d)


FORGED = {
    "1e999 weight": (_forge(lambda d: d["classifiers"][0].update(w1=[1.0, 0.0, 0.0])).replace("[1.0, 0.0, 0.0]",
                                                                                             "[1e999, 0.0, 0.0]"),
                     "non-finite w1"),
    "1e999 version": ('{"format": "m3c2kit-canupo-classifier", "version": 1e999}', "'version' must be an integer"),
    "1e999 min_points": (_forge(lambda d: None).replace('"min_points": 3', '"min_points": 1e999'),
                         "'min_points' must be an integer"),
    "deep nesting": ("[" * 100000 + "]" * 100000, "nested too deeply"),
    "deep nesting in an object": ('{"format": ' + "[" * 100000 + "]" * 100000 + "}", "nested too deeply"),
    "unknown label": (_forge(lambda d: d.update(labels=["1", "3"])), "separates '2', which 'labels' does not list"),
    "label twice": (_forge(lambda d: d.update(labels=["1", "1", "2"])), "lists a class twice"),
    "weights as strings": (_forge(lambda d: d["classifiers"][0].update(w1=["a", "b", "c"])),
                           "'w1' must be a list of numbers"),
    "classifiers a string": (_forge(lambda d: d.update(classifiers="x")), "'classifiers' must be a list"),
    "classifier a number": (_forge(lambda d: d.update(classifiers=[5])), "classifier 0 must be a JSON object"),
    "labels an object": (_forge(lambda d: d.update(labels={"a": 1})), "'labels' must be a list"),
    "label a list": (_forge(lambda d: d["classifiers"][0].update(class1=[1])), "must be a string or an integer"),
    "path of numbers": (_forge(lambda d: d["classifiers"][0].update(path=[1, 2, 3, 4])),
                        "must be a list of pairs of numbers"),
    "huge integer": (_forge(lambda d: None).replace('"w2": [0.0, 1.0, 0.0]', '"w2": [' + "9" * 400 + ', 1, 0]'),
                     "out of range"),
    "info a list": (_forge(lambda d: d.update(info=[1])), "'info' must be a JSON object"),
    "not UTF-8": (b"\xff\xfe\x00{", "not utf-8-sig text"),
}


@pytest.mark.parametrize("case", sorted(FORGED))
def test_a_forged_classifier_is_one_clean_error(case, tmp_path):
    text, words = FORGED[case]
    path = tmp_path / "clf.json"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    with pytest.raises(ClassifierFileError) as caught:
        read_classifier(path)
    assert str(caught.value).startswith(f"{path}: ") and words in str(caught.value)


def test_a_forged_classifier_on_the_command_line(data, tmp_path, capsys):
    path = tmp_path / "clf.json"
    path.write_text("[" * 100000 + "]" * 100000)
    code, err = run(["classify", "apply", data / "a.xyz", "--classifier", path, "-o", tmp_path / "o.csv"], capsys)
    assert code == 1 and one_line(err) == f"{path}: not a classifier (JSON nested too deeply)"


def test_the_reference_classifier_still_reads(tmp_path):
    path = tmp_path / "clf.json"
    path.write_text(json.dumps(_classifier()))
    assert read_classifier(path).labels == ["1", "2"]


# --------------------------------------------------------------- malformed scan positions

MALFORMED_POSITIONS = {
    "origin a number": ('{"1": {"origin": 5, "sigma_range": 0.01, "sigma_scan": 0.001, "sigma_yaw": 0.001}}',
                        "origin must have 3 coordinates"),
    "origin of strings": ('{"1": {"origin": ["a", 0, 0], "sigma_range": 0.01, "sigma_scan": 0.001, '
                          '"sigma_yaw": 0.001}}', "scan position 1"),
    "sigma 1e999": ('{"1": {"origin": [0, 0, 0], "sigma_range": 1e999, "sigma_scan": 0.001, "sigma_yaw": 0.001}}',
                    "sigma_range must be finite"),
    "superscript id": ('{"\u00b2": {"origin": [0, 0, 0], "sigma_range": 0.01, "sigma_scan": 0.001, '
                       '"sigma_yaw": 0.001}}', "ids must be integers"),
    "deep nesting": ('{"1": ' + "[" * 50000 + "]" * 50000 + "}", "nested too deeply"),
    "CSV row too long": ("id,x,y,z,sigma_range,sigma_scan,sigma_yaw\n1,0,0,5,0.01,0.001,0.001,9,9\n",
                         "line 2 has more values than the header"),
    "CSV row too short": ("id,x,y,z,sigma_range,sigma_scan,sigma_yaw\n1,0,0\n", "line 2 has fewer values"),
    "CSV huge id": ("id,x,y,z,sigma_range,sigma_scan,sigma_yaw\n" + "9" * 5000 + ",0,0,5,0.01,0.001,0.001\n",
                    "ids must be integers"),
}


@pytest.mark.parametrize("case", sorted(MALFORMED_POSITIONS))
def test_a_malformed_scan_position_file_is_one_usage_error(case, tmp_path):
    text, words = MALFORMED_POSITIONS[case]
    path = tmp_path / "sp.json"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(UsageError) as caught:
        load_scan_positions(path)
    assert str(path) in str(caught.value) and words in str(caught.value)


# ------------------------------------------------------------------------ the Python API

@pytest.mark.parametrize("call, words", [
    (lambda: m3c2kit.read(None), "path must be a file path"),
    (lambda: m3c2kit.read(3), "path must be a file path"),
    (lambda: m3c2kit.info(np.zeros(3)), "path must be a file path"),
    (lambda: m3c2kit.write("o.csv", "x"), "result must be an m3c2kit.Result"),
    (lambda: m3c2kit.write(None, None), "path must be a file path"),
    (lambda: m3c2kit.io.write_cloud_table("o.csv", np.zeros((2, 3)), [1, 2]), "fields must be a dict"),
    (lambda: m3c2kit.compare(np.random.default_rng(0).random((30, 3)), np.random.default_rng(1).random((30, 3)),
                             normal_scale=1, projection_scale=1, max_depth=1, progress=3), "progress must be a callable"),
])
def test_api_type_errors_name_the_argument(call, words, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(TypeError, match=words):
        call()
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("call, words", [
    (lambda pts: engine.c2c(pts, pts, model="plane", model_neighbours=2**40), "model_neighbours must be an integer"),
    (lambda pts: engine.roughness_by_scale(pts, pts, [1.0], min_points=-1), "min_points must be an integer"),
    (lambda pts: engine.dimensionality(pts, pts, [1.0], threads=2**31), "threads must be an integer"),
    (lambda pts: engine.compute(pts, pts, pts, engine.make_params({}), threads=-1), "threads must be an integer"),
])
def test_engine_arguments_are_checked_before_the_binding(call, words):
    with pytest.raises(UsageError, match=words) as caught:
        call(np.random.default_rng(0).random((20, 3)))
    assert "incompatible" not in str(caught.value) and "std::" not in str(caught.value)


@pytest.mark.parametrize("raised", [
    TypeError("c2c(): incompatible function arguments. The following argument types are supported: ..."),
    ValueError("cannot create std::vector larger than max_size()"),
    ValueError("vector::_M_default_append"),
])
def test_binding_and_cpp_text_never_reaches_a_user(raised):
    with pytest.raises(UsageError) as caught, engine.translated("--option"):
        raise raised
    text = str(caught.value)
    assert text.startswith("--option: ")
    assert all(word not in text for word in ("incompatible", "std::", "max_size", "_M_", "argument types"))


def test_a_parameter_of_the_wrong_type_names_it():
    with pytest.raises(UsageError, match=r"^max_depth: a value the engine cannot take"):
        engine.make_params({"max_depth": "deep"})


# ---------------------------------------------------------------- numpy RuntimeWarnings

@pytest.mark.parametrize("argv", [
    ["simplify", "SAME", "--projection-scale", "1", "-o", "O"],  # no normal anywhere: nothing projected
    ["roughness", "SAME", "--normal-scale", "0.5", "-o", "O"],  # one scale, no roughness
    ["calibrate", "A", "--projection-scales", "0.5", "--max-core", "5", "-o", "O"],  # one scale
    ["compare", "A", "FAR", "-o", "O", *SCALES, "--median", "--lod", "auto"],  # every cylinder empty
    ["compare", "SAME", "SAME", "-o", "O", *SCALES],  # every normal undefined
])
def test_degenerate_inputs_raise_no_runtime_warning(argv, data, tmp_path, capsys):
    np.savetxt(tmp_path / "same.xyz", np.zeros((20, 3)))
    np.savetxt(tmp_path / "far.xyz", np.random.default_rng(3).random((40, 3)) + 100)
    names = {"A": data / "a.xyz", "SAME": tmp_path / "same.xyz", "FAR": tmp_path / "far.xyz", "O": tmp_path / "o.csv"}
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # a numpy warning raises: a traceback, and this test fails
        code, err = run([names.get(a, a) for a in argv], capsys)
    assert code == 0, err
    assert "RuntimeWarning" not in err and "Traceback" not in err


# ------------------------------------------------------------- figures and advice that hold

@pytest.mark.parametrize("argv", [
    ["roughness", "A", "--normal-scale", "0.5,1", "-o", "O", "--plot", "P"],
    ["calibrate", "A", "--projection-scales", "0.5,1", "-o", "O", "--plot", "P"],
    ["classify", "train", "A=ground", "B=vegetation", "-o", "O.json", "--plot", "P"],
], ids=lambda a: a[0] if a[0] != "classify" else "classify train")
@pytest.mark.parametrize("name", ["plot.txt", "plot.foo"])
def test_a_figure_format_matplotlib_cannot_write_is_refused_before_any_output(argv, name, data, tmp_path, capsys):
    # A traceback (matplotlib's ValueError) after -o was written, before.
    pytest.importorskip("matplotlib")
    plot = tmp_path / name
    names = {"A": data / "a.xyz", "A=ground": f"{data / 'a.xyz'}=ground", "B=vegetation": f"{data / 'b.xyz'}=vegetation",
             "O": tmp_path / "o.csv", "O.json": tmp_path / "o.json", "P": plot}
    code, err = run([names.get(a, a) for a in argv], capsys)
    suffix = name.split(".")[1]
    assert one_line(err).startswith(f"--plot {plot}: cannot draw '.{suffix}' figures (supported: ")
    assert code == 2
    assert list(tmp_path.iterdir()) == []  # neither -o nor the figure


@pytest.mark.parametrize("argv", [
    ["roughness", "NAN", "--normal-scale", "0.5,1", "-o", "O"],
    ["calibrate", "NAN", "--projection-scales", "0.5,1", "--bootstrap", "0", "-o", "O"],
    ["c2c", "NAN", "B", "-o", "O"],
    ["simplify", "NAN", "--projection-scale", "0.5", "-o", "O"],
    ["suggest", "NAN", "B", "--sample", "20"],
    ["normals", "NAN", "--normal-scale", "0.5", "-o", "O"],
    ["subsample", "NAN", "--spacing", "0.1", "-o", "O"],
], ids=lambda a: a[0])
def test_every_command_offers_the_drop_nonfinite_its_error_advises(argv, data, tmp_path, capsys):
    # The reader's message advises --drop-nonfinite: commands without it made the advice a usage error.
    rng = np.random.default_rng(11)  # a rough plane dense enough for suggest
    xyz = np.column_stack([rng.uniform(0, 4, (400, 2)), rng.normal(0, 0.01, 400)])
    np.savetxt(tmp_path / "b.xyz", xyz + [0, 0, 0.05])
    xyz[[3, 17]] = np.nan
    np.savetxt(tmp_path / "nan.xyz", xyz)
    names = {"NAN": tmp_path / "nan.xyz", "B": tmp_path / "b.xyz", "O": tmp_path / "o.csv"}
    argv = [names.get(a, a) for a in argv]
    code, err = run(argv, capsys)
    assert code == 1 and one_line(err).endswith("use --drop-nonfinite to drop them")
    code, err = run([*argv, "--drop-nonfinite"], capsys)
    assert code == 0, err


def test_a_spacing_multiple_of_a_cloud_without_spacing_says_so(tmp_path, capsys):
    # One repeated point has no median spacing: '3x' (the default) was called "a non-positive spacing".
    np.savetxt(tmp_path / "same.xyz", np.ones((20, 3)))
    code, err = run(["calibrate", tmp_path / "same.xyz", "--projection-scales", "0.5,1", "-o", tmp_path / "o.csv"],
                    capsys)
    assert code == 2
    assert one_line(err) == ("--spacings: '3x' is a multiple of the median point spacing, which the cloud does not "
                             "have (fewer than two distinct points); give a length")


@pytest.mark.parametrize("kind", ["fifo", "link to a fifo"])
@pytest.mark.parametrize("argv", [
    ["compare", "A", "B", "-o", "S.csv", *SCALES],
    ["subsample", "A", "--spacing", "0.1", "-o", "S.xyz"],
    ["roughness", "A", "--normal-scale", "0.5,1", "-o", "S.csv"],
    ["roughness", "A", "--normal-scale", "0.5,1", "-o", "O", "--plot", "S.png"],
    ["classify", "train", "A=ground", "B=vegetation", "-o", "S.json"],
], ids=lambda a: " ".join(a[:2]) + (" --plot" if "--plot" in a else ""))
def test_an_output_never_replaces_a_special_file(argv, kind, data, tmp_path, capsys):
    # The output is renamed onto its name: as root, `-o /dev/null` replaced the device node with a
    # regular file (exit 0). A FIFO stands for the device here (the test must not risk /dev/null).
    special_name = next(a for a in argv if a.startswith("S."))
    fifo = tmp_path / f"fifo{Path(special_name).suffix}"
    os.mkfifo(fifo)
    target = fifo
    if kind != "fifo":
        target = tmp_path / f"link{fifo.suffix}"
        target.symlink_to(fifo)
    names = {"A": data / "a.xyz", "B": data / "b.xyz", "A=ground": f"{data / 'a.xyz'}=ground",
             "B=vegetation": f"{data / 'b.xyz'}=vegetation", "O": tmp_path / "o.csv", special_name: target}
    code, err = run([names.get(a, a) for a in argv], capsys)
    assert one_line(err) == (f"{target}: not a regular file (a device, FIFO or socket); an output replaces only a "
                             f"regular file: choose another output path")
    assert code == 1
    assert os.path.islink(target) == (kind != "fifo") and stat.S_ISFIFO(os.stat(fifo).st_mode)
    assert not (tmp_path / "o.csv").exists()


HUGE = "9" * 23  # past numpy's int64: an OverflowError traceback before


@pytest.mark.parametrize("flags, label, words", [
    (["--class-map", f"1={HUGE}"], "1", f"--class-map: the code {HUGE} of class '1' is out of range: codes are "
                                        f"integers from -2147483648 to 2147483647"),
    ([], HUGE, f"--class-map: the code {HUGE} of class '{HUGE}' is out of range: codes are integers from "
               f"-2147483648 to 2147483647"),  # a forged classifier's integer label is its own code
    (["--class-map", "1=3,1=4"], "1", "--class-map: 1 is given twice (1=3 and 1=4); give each once"),  # last won
    (["--unclassified", HUGE], "1", f"argument --unclassified: must be an integer from -2147483648 to 2147483647, "
                                    f"got {HUGE}"),
], ids=["class-map code", "integer label", "class-map key twice", "unclassified"])
def test_class_codes_out_of_range_or_given_twice_are_usage_errors(flags, label, words, data, tmp_path, capsys):
    path = tmp_path / "clf.json"
    path.write_text(_forge(lambda d: (d.update(labels=[label, "2"]), d["classifiers"][0].update(class1=label))))
    code, err = run(["classify", "apply", data / "a.xyz", "--classifier", path, "-o", tmp_path / "o.csv", *flags],
                    capsys)
    assert code == 2 and err.splitlines()[-1] == f"m3c2: error: {words}", err
    assert "Traceback" not in err and not (tmp_path / "o.csv").exists()


@pytest.mark.parametrize("call, words", [
    (lambda a: m3c2kit.analysis.roughness_by_scale(a, a, "x"), "diameters must be a number, got 'x'"),
    (lambda a: m3c2kit.analysis.roughness_by_scale(a, a, [0.5], min_points=1.5), "min_points must be an integer"),
    (lambda a: m3c2kit.analysis.c2c(a, a, model="plane", model_neighbours="x"), "model_neighbours must be an integer"),
    (lambda a: m3c2kit.analysis.c2c(a, a, model="plane", model_neighbours=2.5), "model_neighbours must be an integer"),
    (lambda a: m3c2kit.analysis.suggest(a, a, sample=0), "sample must be an integer >= 1, got 0"),
    (lambda a: m3c2kit.analysis.suggest(a, a, sample=-1), "sample must be an integer >= 1, got -1"),
], ids=["diameters a string", "min_points 1.5", "model_neighbours a string", "model_neighbours 2.5", "sample 0",
        "sample -1"])
def test_the_analysis_api_names_a_wrong_argument(call, words):
    # numpy's or int()'s ValueError, a RuntimeWarning ("Mean of empty slice"), or a silent int(2.5) before.
    import m3c2kit.analysis  # noqa: F401 (the package's analysis functions)
    rng = np.random.default_rng(5)
    points = np.column_stack([rng.uniform(0, 4, (200, 2)), rng.normal(0, 0.01, 200)])
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        with pytest.raises(UsageError, match=words):
            call(points)


@pytest.mark.parametrize("prefix", ["", ".", "/", ".."])
def test_a_report_png_prefix_naming_a_folder_is_a_usage_error(prefix, data, tmp_path, capsys):
    # pathlib's "has an empty name" ValueError, a traceback, before.
    code, err = run(["compare", data / "a.xyz", data / "b.xyz", "-o", tmp_path / "o.csv", *SCALES, "--report-png",
                     prefix], capsys)
    shown = prefix or "."  # argparse's Path('') is '.'
    assert one_line(err).startswith(f"--report-png {shown!r} names a folder, not a prefix: give e.g. ")
    assert code == 2 and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("link", [False, True])
def test_the_api_writers_never_replace_a_special_file(link, tmp_path):
    # The command line checks its outputs first (io.collisions); the API's writers reach the atomic
    # writer directly, which refuses them too: write_cloud_table('fifo.csv', ...) replaced the FIFO.
    from m3c2kit.base.errors import CloudWriteError
    from m3c2kit.io import write_cloud_table
    fifo = tmp_path / "fifo.csv"
    os.mkfifo(fifo)
    target = fifo
    if link:
        target = tmp_path / "link.csv"
        target.symlink_to(fifo)
    with pytest.raises(CloudWriteError, match="not a regular file"):
        write_cloud_table(target, np.zeros((2, 3)), {"distance": np.zeros(2)})
    assert stat.S_ISFIFO(os.stat(fifo).st_mode) and os.path.islink(target) == link
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted({"fifo.csv", target.name})
