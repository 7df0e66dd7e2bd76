"""Nothing silently ignored, nothing impossible accepted (issue 31, item 5; docs/errors.md,
"Options that would change nothing"): an option given where it has no effect is a usage error
naming it and what it needs (the parameter table's conditions, m3c2kit.settings.needs, checked
once for the API and every command), and the values of M3C2-EP's and -PM's input files are
checked (a rotation, a positive semidefinite covariance, finite sigmas >= 0, distinct fields)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import m3c2kit
from m3c2kit.run import uncertainty_inputs as ui
from m3c2kit.cli.main import main
from m3c2kit.base.errors import UsageError
from m3c2kit.settings import build_params, resolve

REQUIRED = {"normal_scale": 1.0, "projection_scale": 1.0, "max_depth": 1.0}
NOTHING = "would change nothing in this run"
PAPER_EP = Path("/work/shared/data/pairs/ahk-corepoints-m3c2ep")


# --- Options that would change nothing: the parameter table's conditions -------------------------

# (keywords, the flag named, a word of what it needs); two or more misuses per mode.
MISUSES = [
    # M3C2-EP's inputs without --uncertainty ep (the issue's example: --transform changed nothing)
    (dict(transform="tfM.csv"), "--transform", "--uncertainty ep"),
    (dict(transform="tfM.csv", uncertainty="pm"), "--transform", "--uncertainty ep"),
    (dict(alignment_covariance="Cxx.csv"), "--alignment-covariance", "--uncertainty ep"),
    (dict(scan_positions="sps.json", uncertainty="pm"), "--scan-positions", "--uncertainty ep"),
    (dict(ep_lod="published"), "--ep-lod", "--uncertainty ep"),
    (dict(reduction_point="1,2,3", uncertainty="ep"), "--reduction-point", "--transform"),
    (dict(transform_applied=True, uncertainty="ep"), "--transform-applied", "--transform FILE"),
    # M3C2-PM's inputs without --uncertainty pm
    (dict(precision_fields="a,b,c"), "--precision-fields", "--uncertainty pm"),
    (dict(precision_scales="2,3", uncertainty="ep"), "--precision-scales", "--uncertainty pm"),
    (dict(precision_rule="all"), "--precision-rule", "--uncertainty pm"),
    (dict(ep_weights="matrix", uncertainty="ep", ep_covariance="empirical"), "--ep-weights", "--ep-covariance"),
    # the variance's denominator where no variance is taken
    (dict(variance="population", median=True, normal_source="vertical", normal_scale=None), "--variance", "IQR"),
    (dict(variance="population", median=True, normal_source="vertical", normal_scale=None, bootstrap=10), "--variance",
     "IQR"),
    (dict(variance="population", median=True), None, None),  # accepted: the fitted normals' roughness
    # the bootstrap's seed without the bootstrap
    (dict(seed=7), "--seed", "--lod bootstrap"),
    (dict(seed=7, lod="t"), "--seed", "--lod bootstrap"),
    # the first pass of a search that has none
    (dict(first_pass_depth=0.2, depth_search="single"), "--first-pass-depth", "two-pass"),
    (dict(first_pass_depth=0.2, depth_search="progressive"), "--first-pass-depth", "two-pass"),
    # normal fitting options where normals are imposed (vertical, core)
    (dict(normal_source="vertical"), "--normal-scale", "fitted"),
    (dict(normal_source="core", min_points_normal=5, normal_scale=None), "--min-points-normal", "fitted"),
    (dict(normal_source="vertical", normal_subsample=0.5, normal_scale=None), "--normal-subsample", "fitted"),
    (dict(normal_source="core", orient="-z", normal_scale=None), "--orient", "--normal-source core"),
    # multi-scale options with one scale
    (dict(scale_selection="py4dgeo"), "--scale-selection", "several normal scales"),
    (dict(min_points_multiscale=20, normal_scale="0.5,1"), None, None),  # accepted: two scales
    (dict(min_points_multiscale=20), "--min-points-multiscale", "several normal scales"),
    # LOD options of another LOD
    (dict(median_lod="cloudcompare"), "--median-lod", "--median"),
    (dict(median_lod="cloudcompare", median=True, bootstrap=10), "--median-lod", "not --lod bootstrap"),
    (dict(median_lod="cloudcompare", median=True, uncertainty="pm"), "--median-lod", "--uncertainty pm"),
    (dict(t_statistic=True, uncertainty="pm"), "--t-statistic", "use z"),
    (dict(t_statistic=True, median=True), "--t-statistic", "Maritz-Jarrett"),
]


@pytest.mark.parametrize("keywords, flag, needs", MISUSES, ids=lambda v: str(v) if isinstance(v, dict) else None)
def test_an_option_that_would_change_nothing_is_refused_by_the_api(keywords, flag, needs):
    given = {**REQUIRED, **keywords}
    if flag is None:
        build_params(**{k: v for k, v in given.items() if v is not None})
        return
    with pytest.raises(UsageError) as e:
        build_params(**{k: v for k, v in given.items() if v is not None})
    message = str(e.value)
    assert message.startswith(f"{flag} {NOTHING}: it applies only "), message
    assert needs in message


@pytest.mark.parametrize("keywords", [
    dict(seed=7, bootstrap=10), dict(median_lod="cloudcompare", median=True),
    dict(t_statistic=True, median=True, median_lod="cloudcompare"), dict(first_pass_depth=0.2),
    dict(first_pass_depth=0.2, depth_search="two-pass"), dict(uncertainty="ep", reduction_point="1,2,3",
                                                            transform="tfM.csv"),
    dict(uncertainty="ep", transform_applied=True, transform="tfM.csv"), dict(normal_source="vertical", orient="-z",
                                                                               normal_scale=None),
    dict(uncertainty="pm", precision_fields="a,b,c", precision_rule="all"),
    dict(scale_selection="py4dgeo", normal_scale="0.5:2:0.5"), dict(transform_applied=False),
], ids=str)
def test_the_same_options_where_they_act_are_accepted(keywords):
    resolve({**REQUIRED, **keywords}, "compare", api=True)


def test_t_statistic_contradicting_lod_z_is_refused():
    with pytest.raises(UsageError, match="--lod z contradicts --t-statistic"):
        build_params(lod="z", t_statistic=True, **REQUIRED)


def test_normals_command_options_are_checked_too():
    with pytest.raises(UsageError, match=f"--scale-selection {NOTHING}"):
        m3c2kit.normals(np.zeros((5, 3)), normal_scale=1.0, scale_selection="py4dgeo")
    with pytest.raises(UsageError, match=f"--min-points-multiscale {NOTHING}"):
        build_params("normals", normal_scale=1.0, min_points_multiscale=12)
    build_params("normals", normal_scale="1,2", min_points_multiscale=12)


# --- The command line, in each mode --------------------------------------------------------------

def _plane(path: Path, seed: int, dz: float = 0.0, n: int = 400) -> Path:
    rng = np.random.default_rng(seed)
    xyz = np.column_stack([rng.uniform(0, 4, (n, 2)), dz + rng.normal(0, 0.003, n)])
    np.savetxt(path, xyz, header="x y z", comments="")
    return path


@pytest.fixture
def clouds(tmp_path):
    return _plane(tmp_path / "ref.xyz", 1), _plane(tmp_path / "cmp.xyz", 2, 0.05), tmp_path


BASE = ["--normal-scale", "1", "--projection-scale", "0.5", "--max-depth", "0.5", "--quiet"]


def _compare(clouds, *flags, out="out.csv", base=BASE):
    ref, cmp_, d = clouds
    return main(["compare", str(ref), str(cmp_), "-o", str(d / out), *base, *flags]), d / out


@pytest.mark.parametrize("flags, named", [
    (["--transform", "{d}/tfM.csv"], "--transform"),  # the issue's example: a 5 cm shift changed nothing
    (["--transform", "{d}/tfM.csv", "--tile-size", "2"], "--transform"),
    (["--seed", "3"], "--seed"),
    (["--seed", "3", "--tile-size", "2"], "--seed"),
    (["--grid", "0.5", "--min-points-normal", "5"], "--min-points-normal"),
    (["--first-pass-depth", "0.1", "--compat", "cloudcompare", "--depth-search", "progressive"], "--first-pass-depth"),
    (["--precision-rule", "all", "--compat", "cloudcompare"], "--precision-rule"),
], ids=str)
def test_the_command_line_refuses_an_option_that_would_change_nothing(clouds, capsys, flags, named):
    d = clouds[2]
    np.savetxt(d / "tfM.csv", np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0.05]]), delimiter=",")
    base = BASE[2:] if "--grid" in flags else BASE  # --grid imposes the normals: no --normal-scale
    code, out = _compare(clouds, *[f.format(d=d) for f in flags], base=base)
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.startswith(f"m3c2: error: {named} {NOTHING}") and err.count("\n") == 1, err
    assert not out.exists()


PARAMS_FILE = """[General]
M3C2VER=1
NormalScale=1
NormalMode=0
NormalPreferedOri=4
SearchScale=0.5
SearchDepth=0.5
UseSinglePass4Depth=true
UseMedian=true
"""


def test_a_params_files_values_made_moot_by_the_command_line_are_dropped(clouds, capsys):
    # A params file holds a whole dialog: its NormalScale and orientation under --normal-source
    # vertical (given on the command line) are its state, not asked for; typed options still are.
    d = clouds[2]
    (d / "m3c2.txt").write_text(PARAMS_FILE)
    np.savetxt(d / "core.xyz", [[2.0, 2.0, 0.0, 0.0, 0.0, 1.0]], header="x y z nx ny nz", comments="")
    code, out = _compare(clouds, "--params", str(d / "m3c2.txt"), "--normal-source", "core", "--core",
                         str(d / "core.xyz"), base=["--quiet"], out="core.csv")
    assert code == 0, capsys.readouterr().err  # the file's NormalScale and NormalPreferedOri dropped
    code, out = _compare(clouds, "--params", str(d / "m3c2.txt"), "--normal-source", "vertical", base=["--quiet"])
    assert code == 0, capsys.readouterr().err
    code, out = _compare(clouds, "--params", str(d / "m3c2.txt"), "--normal-source", "vertical", "--normal-scale",
                         "2", base=["--quiet"], out="typed.csv")
    assert code == 2 and not out.exists()
    assert f"--normal-scale {NOTHING}" in capsys.readouterr().err
    # The file asks for a single-pass search: a typed --first-pass-depth would change nothing.
    code, out = _compare(clouds, "--params", str(d / "m3c2.txt"), "--first-pass-depth", "0.1", base=["--quiet"],
                         out="fp.csv")
    assert code == 2 and f"--first-pass-depth {NOTHING}" in capsys.readouterr().err


@pytest.mark.parametrize("command", ["compare", "normals"])
def test_refused_before_any_file_is_read(tmp_path, capsys, command):
    # The inputs do not exist: the option is named first, not the file.
    files, options = (["ref.xyz", "cmp.xyz"], BASE) if command == "compare" else (["ref.xyz"], ["--normal-scale", "1"])
    code = main([command, *(str(tmp_path / f) for f in files), "-o", str(tmp_path / "o.csv"), *options,
                 "--scale-selection", "py4dgeo"])
    assert code == 2
    assert capsys.readouterr().err.startswith(f"m3c2: error: --scale-selection {NOTHING}")


def test_grid_refuses_the_options_it_replaces(clouds, capsys):
    ref, cmp_, d = clouds
    code, out = _compare(clouds, "--grid", "0.5", "--normal-subsample", "0.2", base=BASE[2:])
    assert code == 2
    assert "--normal-subsample would change nothing" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("extra", [[], ["--tile-size", "2"]], ids=["in-memory", "tiled"])
def test_core_normals_without_normal_source_core_is_refused(clouds, capsys, extra):
    d = clouds[2]
    np.savetxt(d / "normals.xyz", np.tile([0.0, 0.0, 1.0], (5, 1)), header="x y z", comments="")
    code, out = _compare(clouds, "--core-normals", str(d / "normals.xyz"), *extra)
    assert code == 2
    assert capsys.readouterr().err.startswith(f"m3c2: error: --core-normals {NOTHING}: it applies only with "
                                              "--normal-source core")
    assert not out.exists()


def test_core_normals_keyword_without_normal_source_core_is_refused_by_the_api():
    pts = np.random.default_rng(3).uniform(0, 2, (50, 3))
    with pytest.raises(UsageError, match=f"core_normals {NOTHING}"):
        m3c2kit.compare(pts, pts, pts[:5], core_normals=np.tile([0.0, 0.0, 1.0], (5, 1)), **REQUIRED)


def test_normal_source_core_without_orient_still_runs(clouds):
    ref, cmp_, d = clouds
    np.savetxt(d / "core.xyz", np.column_stack([np.full(4, 2.0), np.full(4, 2.0), np.zeros(4), np.zeros(4),
                                                np.zeros(4), np.ones(4)]), header="x y z nx ny nz", comments="")
    code = main(["compare", str(ref), str(cmp_), "-o", str(d / "c.csv"), "--core", str(d / "core.xyz"),
                 "--normal-source", "core", "--projection-scale", "0.5", "--max-depth", "0.5", "--quiet"])
    assert code == 0


def test_all_fields_only_with_las_output(clouds, capsys):
    code, out = _compare(clouds, "--all-fields", out="o.csv")
    assert code == 2
    assert "--all-fields would change nothing in this run: it applies only to a LAS/LAZ output" in capsys.readouterr().err
    assert not out.exists()
    code, out = _compare(clouds, "--all-fields", "--tile-size", "2", out="o.ply")
    assert code == 2 and not out.exists()


@pytest.mark.parametrize("extra", [["--tile-size", "2"], []], ids=["tiled", "in-memory"])
def test_verbose_prints_the_parameters_in_every_mode(clouds, capsys, extra):
    code, out = _compare(clouds, "--verbose", *extra, base=BASE[:-1])  # not --quiet
    assert code == 0 and out.exists()
    assert "parameter projection_scale: 0.5" in capsys.readouterr().out


@pytest.mark.parametrize("extra", [[], ["--tile-size", "2"]], ids=["in-memory", "tiled"])
def test_progress_with_quiet_is_refused(clouds, capsys, extra):
    code, out = _compare(clouds, "--progress", *extra)  # BASE has --quiet
    assert code == 2 and not out.exists()
    assert capsys.readouterr().err == ("m3c2: error: --progress would change nothing in this run: -q/--quiet shows "
                                       "no progress bar\n")
    ref, _, d = clouds
    assert main(["normals", str(ref), "-o", str(d / "n.csv"), "--normal-scale", "1", "-q", "--progress"]) == 2


def test_normals_verbose_prints_the_parameters(clouds, capsys):
    ref, _, d = clouds
    assert main(["normals", str(ref), "-o", str(d / "n.csv"), "--normal-scale", "1", "--verbose"]) == 0
    assert "parameter normal_scale: 1" in capsys.readouterr().out


# --- Impossible values in M3C2-EP's and -PM's inputs ---------------------------------------------

def _rotation_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _write(path: Path, m) -> str:
    np.savetxt(path, np.atleast_2d(m), delimiter=",")
    return str(path)


@pytest.mark.parametrize("name, matrix, message", [
    ("reflection", np.column_stack([np.diag([1.0, 1.0, -1.0]), [0, 0, 0.05]]), "is a reflection"),
    ("reflection-4x4", np.vstack([np.column_stack([_rotation_z(0.3) @ np.diag([-1.0, 1, 1]), [1, 2, 3]]),
                                  [0, 0, 0, 1]]), "is a reflection"),
    ("shear", np.column_stack([[[1, 0.05, 0], [0, 1, 0], [0, 0, 1]], [0, 0, 0]]), "is not a rotation"),
    ("scale", np.column_stack([1.02 * np.eye(3), [0, 0, 0]]), "is not a rotation"),
    ("nan", np.column_stack([np.eye(3), [0, np.nan, 0]]), "non-finite"),
    ("last-row", np.vstack([np.eye(3, 4), [0, 0, 0.5, 1]]), "last row of a 4x4 transformation must be 0 0 0 1"),
], ids=lambda v: v if isinstance(v, str) else "")
def test_a_transform_that_is_not_a_rigid_motion_is_refused_naming_the_file(tmp_path, name, matrix, message):
    path = _write(tmp_path / f"{name}.csv", matrix)
    with pytest.raises(UsageError) as e:
        ui.transform_matrix(path)
    assert str(e.value).startswith(f"--transform {path}: ") and message in str(e.value), str(e.value)
    with pytest.raises(UsageError, match=message):  # as arrays (the API) too
        ui.transform_matrix(matrix)


def test_a_rotation_is_accepted_as_3x4_or_4x4(tmp_path):
    m = np.column_stack([_rotation_z(0.4), [1.0, -2.0, 0.5]])
    three = ui.transform_matrix(_write(tmp_path / "a.csv", m))
    four = ui.transform_matrix(_write(tmp_path / "b.csv", np.vstack([m, [0, 0, 0, 1]])))
    assert three.shape == four.shape == (3, 4) and np.array_equal(three, four)
    if PAPER_EP.exists():  # a 12-parameter registration's tfM (5e-4 from orthonormal) and its Cxx
        assert ui.transform_matrix(str(PAPER_EP / "tfM.csv")).shape == (3, 4)
        assert ui.alignment_covariance(str(PAPER_EP / "Cxx.csv")).shape == (12, 12)


def _covariance(seed: int = 5, rank: int = 12) -> np.ndarray:
    a = np.random.default_rng(seed).normal(0, 1e-3, (12, rank))
    return a @ a.T


@pytest.mark.parametrize("name, make, message", [
    ("negative-eigenvalue", lambda c: _indefinite(c), "not positive semidefinite: eigenvalue -"),
    ("asymmetric", lambda c: c + np.triu(np.full((12, 12), 1e-9), 1), "is not symmetric: row 1, column 2"),
    ("negative-variance", lambda c: _with(c, (4, 4), -1e-6), "negative variance"),
    ("nan", lambda c: _with(c, (2, 7), np.nan), "non-finite"),
], ids=lambda v: v if isinstance(v, str) else "")
def test_an_impossible_covariance_is_refused_naming_the_file(tmp_path, name, make, message):
    c = make(_covariance())
    path = _write(tmp_path / f"{name}.csv", c)
    with pytest.raises(UsageError) as e:
        ui.alignment_covariance(path)
    assert str(e.value).startswith(f"--alignment-covariance {path}: ") and message in str(e.value), str(e.value)


def _indefinite(c: np.ndarray) -> np.ndarray:
    # Symmetric, positive diagonal, one eigenvalue at -1 % of the largest: looks like a covariance.
    w, v = np.linalg.eigh(c)
    w[0] = -0.01 * w[-1]
    out = (v * w) @ v.T
    return (out + out.T) / 2


def _with(c: np.ndarray, at: tuple, value: float) -> np.ndarray:
    c = c.copy()
    c[at] = c[at[::-1]] = value
    return c


def test_a_rank_deficient_covariance_rounded_in_text_is_accepted(tmp_path):
    # 6 parameters' motion propagated to 12: rank 6, eigenvalues at 0 that rounding makes +-1e-12.
    c = _covariance(rank=6)
    path = tmp_path / "rounded.csv"
    np.savetxt(path, c, delimiter=",", fmt="%.6e")
    assert np.linalg.eigvalsh(np.loadtxt(path, delimiter=","))[0] < 0  # rounding made it indefinite
    ui.alignment_covariance(str(path))


def test_the_issues_negative_eigenvalue_covariance_fails_the_run_naming_the_file(tmp_path, capsys):
    ref, cmp_ = _plane(tmp_path / "ref.xyz", 1), _plane(tmp_path / "cmp.xyz", 2, 0.05)
    for p, seed in ((ref, 1), (cmp_, 2)):  # a scan-position id column
        xyz = np.loadtxt(p, skiprows=1)
        np.savetxt(p, np.column_stack([xyz, np.ones(len(xyz))]), header="x y z scan", comments="")
    (tmp_path / "sps.json").write_text(json.dumps({"1": {"origin": [-10, 2, 2], "sigma_range": 0.003,
                                                         "sigma_scan": 0.0003, "sigma_yaw": 0.0003}}))
    cxx = _write(tmp_path / "Cxx.csv", _indefinite(_covariance()))
    out = tmp_path / "ep.csv"
    code = main(["compare", str(ref), str(cmp_), "-o", str(out), *BASE, "--uncertainty", "ep", "--scan-positions",
                 str(tmp_path / "sps.json"), "--scan-position-field", "scan", "--alignment-covariance", cxx])
    err = capsys.readouterr().err
    assert code == 2 and f"--alignment-covariance {cxx}: the covariance is not positive semidefinite" in err
    assert not out.exists()


@pytest.mark.parametrize("names", ["sx,sx,sz", "a, b ,a"])
def test_precision_fields_must_be_distinct(names):
    with pytest.raises(UsageError, match="three distinct field names"):
        ui.carried({"uncertainty": "pm", "precision_fields": names})
    with pytest.raises(UsageError, match="three distinct field names"):
        ui.precision_array({"sx": [1.0], "sz": [1.0], "a": [1.0], "b": [1.0]}, names)


ENTRY = {"origin": [1, 2, 3], "sigma_range": 0.005, "sigma_scan": 0.0003, "sigma_yaw": 0.0004}


@pytest.mark.parametrize("change, message", [
    ({"sigma_range": -0.005}, "sigma_range is a standard deviation and must be >= 0"),
    ({"sigma_range_ppm": -2}, "sigma_range_ppm is a standard deviation and must be >= 0"),
    ({"sigma_yaw": float("inf")}, "sigma_yaw must be finite"),
    ({"origin": [1, float("nan"), 3]}, "origin y must be finite"),
], ids=str)
def test_scan_position_values_out_of_range_name_the_file_and_the_id(tmp_path, change, message):
    path = tmp_path / "sps.json"
    path.write_text(json.dumps({"1": ENTRY, "7": {**ENTRY, **change}}))
    with pytest.raises(UsageError) as e:
        ui.load_scan_positions(path)
    assert str(e.value).startswith(f"{path}: scan position 7: {message}"), str(e.value)


def test_scan_position_listed_twice_or_fractional_is_refused(tmp_path):
    path = tmp_path / "sps.csv"
    path.write_text("id,x,y,z,sigma_range,sigma_scan,sigma_yaw\n3,1,2,3,0.005,0.0003,0.0004\n"
                    "3,4,5,6,0.005,0.0003,0.0004\n")
    with pytest.raises(UsageError, match=f"{path}: scan position 3 is listed more than once"):
        ui.load_scan_positions(path)
    table = np.array([[1.5, 0, 0, 0, 0.005, 0, 0.0003, 0.0004]])
    with pytest.raises(UsageError, match="ids must be integers"):
        ui.shared_inputs({"uncertainty": "ep", "scan_positions": table}, None, None)


# --- The analysis commands: options that would change nothing, impossible values -----------------

@pytest.mark.parametrize("flags, named, needs", [
    (["--model-knn", "10"], "--model-knn", "--model plane"),  # C2C has no local model: k unused
    (["--model", "none", "--rule", "model"], "--rule", "--model plane"),
    (["--model-radius", "0.5"], "--model-radius", "--model plane"),
    (["--model", "plane", "--model-radius", "0.5", "--model-knn", "8"], "--model-knn", "--model-radius chooses"),
], ids=str)
def test_c2c_refuses_model_options_without_the_model_they_tune(clouds, capsys, flags, named, needs):
    ref, cmp_, d = clouds
    code = main(["c2c", str(ref), str(cmp_), "-o", str(d / "c2c.csv"), *flags])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith(f"m3c2: error: {named} {NOTHING}") and needs in err, err
    assert not (d / "c2c.csv").exists()
    from m3c2kit.analysis import c2c  # the API refuses the same
    keywords = {"--model-knn": "model_neighbours", "--rule": "rule", "--model-radius": "model_radius"}
    given = {keywords[f]: (v if f == "--rule" else float(v)) for f, v in zip(flags[::2], flags[1::2]) if f in keywords}
    with pytest.raises(UsageError, match=f"{named} {NOTHING}"):
        c2c(np.zeros((3, 3)), np.zeros((3, 3)), model=dict(zip(flags[::2], flags[1::2])).get("--model", "none"),
            **given)


def test_c2c_model_options_where_they_act_are_accepted(clouds, capsys):
    ref, cmp_, d = clouds
    assert main(["c2c", str(ref), str(cmp_), "-o", str(d / "a.csv"), "--model", "plane", "--model-knn", "8",
                 "--rule", "model", "-q"]) == 0, capsys.readouterr().err
    assert main(["c2c", str(ref), str(cmp_), "-o", str(d / "b.csv"), "-q"]) == 0, capsys.readouterr().err


def test_simplify_refuses_a_normal_scale_with_vertical_normals(clouds, capsys):
    ref, _, d = clouds
    code = main(["simplify", str(ref), "--projection-scale", "0.5", "--vertical", "--normal-scale", "1", "-o",
                 str(d / "s.csv")])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith(f"m3c2: error: --normal-scale {NOTHING}") and "--vertical" in err, err
    assert not (d / "s.csv").exists()
    # a d whose default D = 2 d overflows names the option given, not the --normal-scale left out
    code = main(["simplify", str(ref), "--projection-scale", "1e308", "-o", str(d / "s.csv")])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("m3c2: error: --projection-scale 1e+308 is too large"), err


@pytest.mark.parametrize("l0", ["nan", "-1", "inf", "0"])
def test_roughness_refuses_an_impossible_l0(clouds, capsys, l0):
    ref, _, d = clouds
    code = main(["roughness", str(ref), "--normal-scale", "0.5,1", "--l0", l0, "-o", str(d / "r.csv")])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("m3c2: error: --l0 must be finite and > 0"), err
    assert not (d / "r.csv").exists()
    # named before the cloud is read (a missing one here) and the scales computed
    code = main(["roughness", str(d / "missing.xyz"), "--normal-scale", "0.5,1", "--l0", l0, "-o", str(d / "r.csv")])
    assert code == 2 and "--l0 must be finite and > 0" in capsys.readouterr().err
    from m3c2kit.analysis import fit_scaling  # the API: sigma(l0) was NaN or 0
    with pytest.raises(UsageError, match="--l0 must be finite and > 0"):
        fit_scaling([0.5, 1.0], [0.01, 0.02], l0=float(l0))


def test_matrices_past_the_float_range_are_refused_without_a_numpy_warning(tmp_path):
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # "overflow encountered in matmul" reached stderr
        with pytest.raises(UsageError, match="is not a rotation"):
            ui.transform_matrix(np.column_stack([1e308 * np.eye(3), [0, 0, 0]]))
        # every eigenvalue overflows (NaN passed the semidefinite test): the LODs were all NaN, exit 0
        path = _write(tmp_path / "huge.csv", np.full((12, 12), 1e308))
        with pytest.raises(UsageError, match=f"--alignment-covariance {path}: .* eigenvalues overflow"):
            ui.alignment_covariance(path)


@pytest.mark.parametrize("argv, words", [
    (["compare", "REF", "CMP", "-o", "OUT", *BASE, "--crs", ""], "--crs ''"),  # no CRS assigned, exit 0
    (["classify", "train", "REF", "--label-field", "z", "--label-values", "", "-o", "OUT.json"],
     "--label-values is empty: give KEY=VALUE items separated by commas"),  # every value a label
    (["classify", "train", "REF=a", "CMP=b", "--scales", "", "-o", "OUT.json"], "--scales is empty"),  # the defaults
], ids=["--crs", "--label-values", "--scales"])
def test_an_option_given_an_empty_value_is_refused_not_dropped(clouds, capsys, argv, words):
    ref, cmp_, d = clouds
    names = {"REF": str(ref), "CMP": str(cmp_), "REF=a": f"{ref}=a", "CMP=b": f"{cmp_}=b", "OUT": str(d / "o.csv"),
             "OUT.json": str(d / "o.json")}
    code = main([names.get(a, a) for a in argv])
    err = capsys.readouterr().err
    assert code == 2 and words in err and err.count("\n") == 1, err
    assert not (d / "o.csv").exists() and not (d / "o.json").exists()


def test_an_empty_class_map_is_refused_not_dropped():
    from m3c2kit.cli.classify import class_codes
    from types import SimpleNamespace
    for spec in ("", " , "):
        with pytest.raises(UsageError, match="--class-map is empty"):
            class_codes(SimpleNamespace(labels=["2", "5"]), spec)
    assert class_codes(SimpleNamespace(labels=["2", "5"]), None) == {"2": 2, "5": 5}
