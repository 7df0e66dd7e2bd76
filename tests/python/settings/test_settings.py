"""The parameter table (m3c2kit.settings) and the engine facade (m3c2kit.engine): one schema for
the C++ struct, the binding and the table; everything derived from the table (the command line,
the API keywords, the params-file mapping, the docs) agrees with it; issue 12's defects."""
from __future__ import annotations

import ast
import math
import pickle
import re
from pathlib import Path

import numpy as np
import pytest

import m3c2kit
from m3c2kit import _core, engine
from m3c2kit.cli.compare import compare_settings
from m3c2kit.cli.main import make_parser
from m3c2kit.base.errors import UsageError
from m3c2kit.settings import PARAMETERS, build_params, by_name, docs, parameters_of
from m3c2kit.settings import cloudcompare_params, orientation
from synthetic import noisy_plane_pair

ROOT = Path(__file__).resolve().parents[3]
REQUIRED = {"normal_scale": 1.0, "projection_scale": 1.0, "max_depth": 1.0}


def _struct_fields(header: str, struct: str) -> list[str]:
    """Member names of `struct` in a C++ header, read from the source (an independent list)."""
    text = (ROOT / "include" / "m3c2" / header).read_text()
    body = re.search(r"struct %s \{(.*?)\n\};" % struct, text, re.S).group(1)
    body = re.sub(r"//[^\n]*", "", body)
    while "<" in body:
        body = re.sub(r"<[^<>]*>", "", body)  # template arguments hold commas
    body = re.sub(r"\{[^{}]*\}", "", body)  # brace initialisers hold commas
    names = []
    for statement in body.split(";"):
        statement = re.sub(r"=[^,]*", "", statement).strip()  # "double a = 1.0, b = 1.0" -> "double a, b"
        if statement and "(" not in statement:
            first, *rest = statement.split(",")
            names += [first.split()[-1]] + [n.strip() for n in rest]
    return names


def test_the_struct_the_binding_and_the_table_have_the_same_fields():
    struct = _struct_fields("params.hpp", "Params")
    orientation = _struct_fields("params.hpp", "Orientation")
    expected = [f for name in struct for f in ([f"orientation_{o}" for o in orientation]
                                                if name == "orientation" else [name])]
    assert list(engine.PARAM_FIELDS) == expected
    table_fields = [f for p in PARAMETERS if p.engine is not None and p.engine.struct == "Params"
                    for f in p.engine.fields]
    assert sorted(table_fields) == sorted(expected)  # every field once, none twice


def test_the_result_schema_is_the_engine_struct():
    assert sorted(engine.RESULT_FIELDS + engine.OPTIONAL_RESULT_FIELDS) == sorted(_struct_fields("result.hpp", "Result"))
    fields = [f for f in m3c2kit.Result.__dataclass_fields__]
    assert fields == ["core", *engine.RESULT_FIELDS, "params", *engine.OPTIONAL_RESULT_FIELDS]


def test_params_pickle_with_every_field():
    # Every field set, in runs where each acts (an option that would change nothing is refused:
    # m3c2kit.settings.needs), so the fields of eq. (1), its median, PM and EP in four Params.
    runs = [build_params(normal_scale="1,2", projection_scale=2.5, max_depth=3, orient="1,2,3", median=True,
                         variance="population", scale_selection="cloudcompare", min_points_normal=5,
                         min_points_multiscale=12, first_pass_depth=1.5, positive_search_only=True,
                         registration_error=0.1, confidence=0.9, min_points=6, bootstrap=10,
                         seed=2**64 - 1, normal_subsample=0.5),
            build_params(median=True, median_lod="cloudcompare", **REQUIRED),
            build_params(uncertainty="pm", precision_rule="all", precision_scales="2,0.5", **REQUIRED),
            build_params(uncertainty="ep", ep_covariance="mean-of-points", ep_lod="published", ep_weights="matrix",
                         **REQUIRED)]
    for p in runs:
        q = pickle.loads(pickle.dumps(p))
        assert engine.params_fields(q) == engine.params_fields(p)
        assert engine.params_fields(q) != engine.default_fields()  # the values travelled, not defaults
    assert runs[0].depth_search == _core.DepthSearch.two_pass and runs[0].bootstrap_seed == 2**64 - 1
    assert runs[0].lod == _core.Lod.bootstrap and runs[2].precision_scale2 == 0.5


def test_defaults_come_from_the_engine_struct():
    # min_points = 4 is written in params.hpp only; --compat cloudcompare's 5 in the table only.
    assert by_name()["min_points"].default_for() == _core.Params().min_points == 4
    assert by_name()["min_points"].default_for("cloudcompare") == 5
    assert by_name()["variance"].default_for() == "sample"
    assert by_name()["depth_search"].default_for() == "single"
    # Not given, --orient is one rule (settings.orientation): the scan positions when the cloud has
    # them, else +z.
    assert by_name()["orient"].default_for() is None
    assert orientation.orientation(None)[0] == (0.0, 0.0, 1.0)
    assert orientation.orientation(None, scan_positions=np.array([[1.0, 2.0, 3.0]]))[1].tolist() == [[1.0, 2.0, 3.0]]
    p = build_params(**REQUIRED)
    defaults = engine.default_fields()
    for name in ("min_points", "min_points_normal", "min_points_multiscale", "confidence", "variance"):
        assert getattr(p, name) == getattr(_core.Params(), name), name
    assert defaults["orientation_direction"] == [0.0, 0.0, 1.0]


def test_unknown_keyword_names_the_closest_and_the_valid_ones():
    ref, cmp = noisy_plane_pair(n=20)
    with pytest.raises(UsageError) as caught:
        m3c2kit.compare(ref, cmp, min_point=3, **REQUIRED)
    message = str(caught.value)
    assert "'min_point'" in message and "did you mean 'min_points'?" in message
    assert "valid parameters:" in message and "registration_error" in message
    with pytest.raises(UsageError, match="did you mean 'normal_scale'"):
        m3c2kit.normals(ref, normal_scal=1.0)


def test_min_points_normal_beyond_uint32_is_a_usage_error_naming_it():
    ref, cmp = noisy_plane_pair(n=20)
    with pytest.raises(UsageError, match="--min-points-normal must be an integer >= 3.*at most 4294967295"):
        m3c2kit.compare(ref, cmp, min_points_normal=2**40, **REQUIRED)


def test_core_is_the_api_name_of_core_points_too():
    ref, cmp = noisy_plane_pair(n=30)
    core = ref[::7].copy()
    params = {"normal_scale": 0.3, "projection_scale": 0.2, "max_depth": 0.5}
    a = m3c2kit.compare(ref, cmp, core=core, **params)
    b = m3c2kit.compare(ref, cmp, core, **params)
    assert np.isfinite(a.distance).mean() > 0.9
    assert len(a) == len(core)
    np.testing.assert_array_equal(a.distance, b.distance)
    with pytest.raises(UsageError, match="not both"):
        m3c2kit.compare(ref, cmp, core, core=core, **params)


#: The options each of those needs to act at all (alone they are refused as changing nothing).
NEEDS = {"scale_selection": ["--normal-scale", "1,2"], "min_points_multiscale": ["--normal-scale", "1,2"],
         "median_lod": ["--median"], "seed": ["--bootstrap", "9"], "precision_rule": ["--uncertainty", "pm"],
         "precision_scales": ["--uncertainty", "pm"], "ep_covariance": ["--uncertainty", "ep"],
         "ep_lod": ["--uncertainty", "ep"], "ep_weights": ["--uncertainty", "ep", "--ep-covariance", "independent"]}


@pytest.mark.parametrize("param", [p for p in PARAMETERS if p.engine is not None and p.engine.struct == "Params"],
                         ids=lambda p: p.name)
def test_every_engine_parameter_is_reachable_from_the_command_line(param, tmp_path):
    values = {"normal_scale": "2,3", "normal_source": "mean", "scale_selection": "cloudcompare",
              "min_points_normal": "7", "min_points_multiscale": "11", "normal_subsample": "0.25",
              "orient": "1,2,3", "projection_scale": "2.5", "max_depth": "4", "depth_search": "progressive",
              "first_pass_depth": "1.5", "variance": "population", "registration_error": "0.125",
              "confidence": "0.9", "min_points": "6", "bootstrap": "9", "seed": "17", "lod": "t",
              "median_lod": "cloudcompare", "uncertainty": "pm", "precision_rule": "all",
              "precision_scales": "2,3", "ep_covariance": "mean-of-points", "ep_lod": "published",
              "ep_weights": "matrix", "error_model": str(tmp_path / "model.json")}
    if param.name == "error_model":  # a file: m3c2 variogram's model, fitted at the run's d
        from m3c2kit.analysis.error_model import Component, ErrorModel, save
        save(values["error_model"], ErrorModel(0.0, (Component("spherical", 1e-4, 5.0),), 2.0, mean_u2=0.0))
    argv = ["compare", "r.xyz", "c.xyz", "-o", "o.csv", "--projection-scale", "2", "--max-depth", "3",
            "--normal-scale", "1"]
    argv += [param.flag] if param.cli_type is None else [param.flag, values[param.name]]
    argv += NEEDS.get(param.name, [])  # what the option acts with (m3c2kit.settings.needs)
    settings = compare_settings(make_parser().parse_args(argv))
    settings.pop("position", None)
    p = build_params(**settings)
    default = build_params(**{k: v for k, v in settings.items() if k != param.name}, **(
        {param.name: REQUIRED[param.name]} if param.name in REQUIRED else {}))
    changed = [f for f in param.engine.fields if getattr(p, f) != getattr(default, f)]
    assert changed, f"{param.flag} did not reach the engine"


def test_lod_switches_agree_with_lod():
    assert build_params(t_statistic=True, **REQUIRED).lod == _core.Lod.auto
    assert build_params(bootstrap=5, **REQUIRED).lod == _core.Lod.bootstrap
    assert build_params(lod="t", **REQUIRED).lod == _core.Lod.t
    with pytest.raises(UsageError, match="--lod z contradicts --bootstrap"):
        build_params(lod="z", bootstrap=5, **REQUIRED)
    with pytest.raises(UsageError, match="--lod bootstrap needs --bootstrap N"):
        build_params(lod="bootstrap", **REQUIRED)


def test_normals_takes_the_shared_options():
    args = make_parser().parse_args(["normals", "in.xyz", "-o", "o.csv", "--normal-scale", "1",
                                     "--variance", "population", "--min-points-multiscale", "5"])
    assert args.variance == "population" and args.min_points_multiscale == 5
    assert {p.name for p in parameters_of("normals")} >= {"normal_scale", "orient", "normal_subsample", "threads"}


def test_help_shows_each_default():
    assert by_name()["min_points"].help_text().endswith("(default 4; 5 with --compat cloudcompare)")
    assert "(default 0.95)" in by_name()["confidence"].help_text()


def test_every_cloudcompare_key_is_mapped_by_the_table_or_deliberately_not():
    mapped = {k for p in PARAMETERS for k in p.cloudcompare_keys}
    assert mapped.isdisjoint(cloudcompare_params.NON_PARAMETER_KEYS)
    assert mapped | set(cloudcompare_params.NON_PARAMETER_KEYS) == set(cloudcompare_params._KEY_TYPES)


def test_docs_option_table_is_up_to_date():
    text = (ROOT / "docs" / "cli.md").read_text(encoding="utf-8")
    assert docs.markdown_table() in text, "run: python -m m3c2kit.settings.docs docs/cli.md"


def test_engine_geometry_comes_from_the_engine():
    p = build_params(normal_scale="1,6", projection_scale=2, max_depth=3)
    reach = max(6 / 2, math.hypot(2 / 2, 3))  # the sphere of the largest D, or the cylinder
    assert engine.neighbourhood_reach(p) == pytest.approx(reach, rel=1e-15)
    assert reach < engine.tile_halo(p) <= reach * (1 + 2e-6) + 1e-6
    assert engine.MAX_CELLS_PER_AXIS == 2.0**40
    assert engine.INDEX_MEMORY == {"bytes_per_point": 44.0, "copy_bytes_per_point": 24.0, "moments_bytes_per_point": 30.0,
                                   "overhead": 1.05, "bytes_per_core_point": 120.0}


def test_engine_errors_are_translated_once():
    p = _core.Params()
    with pytest.raises(UsageError, match="min_points"):
        engine.make_params({"min_points": 2**40})  # nanobind's TypeError
    with pytest.raises(UsageError, match="--grid"):
        engine.grid_core_points(np.array([[0.0, 0, 0], [1e15, 0, 0]]), 1e-3, "--grid")
    with pytest.raises(UsageError):
        engine.compute(np.zeros((0, 3)), np.zeros((1, 3)), np.zeros((1, 3)), p)


@pytest.mark.slow
def test_only_the_facade_imports_the_binding():
    offenders = []
    for f in (ROOT / "python" / "m3c2kit").rglob("*.py"):
        for node in ast.walk(ast.parse(f.read_text())):
            names = [a.name for a in getattr(node, "names", [])] if isinstance(node, (ast.Import, ast.ImportFrom)) else []
            module = getattr(node, "module", None) or ""
            if any(n.split(".")[-1] == "_core" for n in names) or module.split(".")[-1] == "_core":
                offenders.append(str(f.relative_to(ROOT)))
    # The facade is the engine package: __init__.py, and its modules by concept (planes.py: PB-M3C2).
    assert offenders and all(o.startswith("python/m3c2kit/engine/") for o in offenders), offenders
