"""THE parameter table: every parameter of `m3c2 compare` (and the ones `m3c2 normals` shares)
once, with its flag, type and range, default, CloudCompare-compatible default, engine field(s),
help text, paper section, CloudCompare params-file key(s) and py4dgeo name; then the series steps'
options (:mod:`.series_rows`, their defaults from the steps' engine structs), m3c2 pbm3c2's
(:mod:`.pbm3c2_rows`) and m3c2 register's (:mod:`.registration_rows`).

Derived from it: the command line's options (m3c2kit.cli.main), the API's keyword check and defaults
(:mod:`m3c2kit.settings.resolve`), the building of the engine's Params, the params-file mapping
(:mod:`m3c2kit.settings.cloudcompare_params`) and the docs' option table
(:mod:`m3c2kit.settings.docs`, docs/cli.md). Defaults of engine parameters are the engine's own
(include/m3c2/params.hpp), read through :func:`m3c2kit.engine.default_fields`: they are written
nowhere else. How to add a parameter: docs/architecture.md.
"""
from __future__ import annotations

from .. import engine
from . import error_model, orientation, parsers
from .row import FROM_ENGINE, SAME, EngineField, Parameter, _shown, enum, same, unset_is_zero
from .pbm3c2_rows import PBM3C2_ROWS
from .registration_rows import REGISTRATION_ROWS
from .series_rows import SERIES_ROWS
from .needs import (A_VARIANCE, BOOTSTRAP, EP, EP_OR_REGISTRATION, EQ1, FITTED_NORMALS, MOVED_OR_PROPAGATED, NOT_CORE_NORMALS,
    PARAMETRIC_MEDIAN, PM, SEVERAL_SCALES, TRANSFORM, TWO_PASS, WEIGHTED_CENTRES, WELCH_T, Needs)
from .parsers import (UINT32_MAX, UINT64_MAX, Choice, Flag, Integer, Positives, Real, RealOrRegistration, Scales,
                      Text)

__all__ = ["Parameter", "EngineField", "PARAMETERS", "FROM_ENGINE", "SAME", "by_name", "parameters_of"]


def _orientation_fields(spec, read_points=None, core_points=None, scan_positions=None, **_) -> dict:
    direction, points, away = orientation.orientation(spec, read_points, core_points, scan_positions)
    return {"orientation_direction": list(direction), "orientation_points": points.ravel().tolist(),
            "orientation_away": away}


def _orientation_name(f: dict) -> str:
    axes = {tuple(v): k for k, v in parsers.AXES.items()}
    if f["orientation_points"]:
        return "away:points" if f["orientation_away"] else "points"
    return axes.get(tuple(f["orientation_direction"]), "+z")


ORIENTATION = EngineField(("orientation_direction", "orientation_points", "orientation_away"),
                          _orientation_fields, _orientation_name)
PRECISION_SCALES = EngineField(("precision_scale1", "precision_scale2"),
                               lambda v, **_: {"precision_scale1": v[0], "precision_scale2": v[1]},
                               lambda f: [f["precision_scale1"], f["precision_scale2"]])
# --error-model: the model's excess variance (the stable distances' total sill minus their mean
# s1^2/n1 + s2^2/n2) inside eq. (1)'s square root (docs/algorithm.md, "Spatially correlated
# errors"); resolve's rule checks its d against the run's.
ERROR_MODEL = EngineField(("correlated_variance",),
                          lambda v, **_: {"correlated_variance": 0.0 if v is None
                                          else error_model.for_compare(v).excess_variance()},
                          lambda f: None)
STATISTIC = EngineField(("statistic",), lambda v, **_: {"statistic": "median" if v else "mean"},
                        lambda f: f["statistic"] == "median")


#: --fdr-method acts with --fdr only.
FDR = Needs(lambda v: v.get("fdr") is not None, "with --fdr Q (the false-discovery control it chooses)")
COUNT = Integer(1, UINT32_MAX, "an integer >= 1")
PLANE_POINTS = Integer(3, UINT32_MAX, "an integer >= 3 (a plane needs 3 points)")
NORMAL_SOURCES = ("reference", "compared", "mean", "vertical", "horizontal", "core")
DEPTH_SEARCHES = ("single", "two-pass", "progressive")
BOTH = ("compare", "normals")

PARAMETERS: tuple[Parameter, ...] = (
    # Normals (section 3.1.2, 3.2)
    Parameter("normal_scale", "--normal-scale", Scales(), label='Normal scale D (diameter)', section="3.1.2, 3.2", engine=unset_is_zero(
        "normal_diameters", []), cli_type=str, cloudcompare_keys=("NormalScale", "NormalMinScale", "NormalStep",
                                                                   "NormalMaxScale"),
              py4dgeo="normal_radii (radii: D / 2)", commands=BOTH, needs=(FITTED_NORMALS,),
              help="D, the normal scale: DIAMETER of the sphere of neighbours (as in the paper and CloudCompare). "
                   "One value, a list '0.5,1,2' or a range 'MIN:MAX:STEP' (multi-scale: the most planar scale "
                   "wins); needed unless --normal-source is vertical or core, and chosen from the data by m3c2 "
                   "compare when not given"),
    Parameter("normal_source", "--normal-source", Choice(*NORMAL_SOURCES), label='Normals from', section="3.1.2",
              engine=enum("normal_source"), cli_type=str, cloudcompare_keys=("NormalMode",),
              help="where normals come from"),
    Parameter("scale_selection", "--scale-selection", Choice("most-planar", "cloudcompare", "py4dgeo"),
              label='Multi-scale rule', section="3.2", engine=enum("scale_selection"), cloudcompare="cloudcompare", cli_type=str,
              commands=BOTH, needs=(FITTED_NORMALS, SEVERAL_SCALES), help="multi-scale rule: the most planar scale (the paper's), CloudCompare's, or "
                                  "py4dgeo's largest (lambda2 - lambda3) / lambda1"),
    Parameter("min_points_normal", "--min-points-normal", PLANE_POINTS, label='Fewest points for a normal', section="3.1.2",
              engine=same("min_points_normal"), cli_type=int, commands=BOTH, needs=(FITTED_NORMALS,),
              help="fewest neighbours for a plane fit at one scale"),
    Parameter("min_points_multiscale", "--min-points-multiscale", PLANE_POINTS, label='Fewest points at the chosen scale', section="3.2",
              engine=same("min_points_multiscale"), cli_type=int, commands=BOTH,
              needs=(FITTED_NORMALS, SEVERAL_SCALES),
              help="fewest neighbours at the scale multi-scale normals choose"),
    Parameter("normal_subsample", "--normal-subsample", Real(), label='Normals on a cloud subsampled to', section="5.1",
              engine=unset_is_zero("normal_subsample_spacing"), commands=BOTH, needs=(FITTED_NORMALS,),
              help="compute normals on the cloud subsampled to this minimum spacing"),
    Parameter("orient", "--orient", parsers.Orientation(), label='Normal orientation', section="3.1.2", engine=ORIENTATION, default=None,
              cli_type=str, cloudcompare_keys=("NormalPreferedOri",), py4dgeo="orientation_vector",
              commands=BOTH, needs=(NOT_CORE_NORMALS,),
              help="normal orientation: +z -z +x -x +y -y; towards a point X,Y,Z, the closest point of a "
                   "FILE (scanner positions), origin (0,0,0), the core points' barycentre, or the sensor "
                   "(E57 scan positions); away:POINT for away from a point (away:barycentre, away:origin, "
                   "away:sensor, away:X,Y,Z). Default: the sensor when the cloud the core points come from "
                   "(else the reference) has scan positions, else +z"),
    # Projection (section 3.1.3)
    Parameter("projection_scale", "--projection-scale", Real(), label='Projection scale d (cylinder diameter)', section="3.1.3",
              engine=same("projection_diameter"), default=None, cloudcompare_keys=("SearchScale",),
              py4dgeo="cyl_radius (a radius: d / 2)", help="d: DIAMETER of the projection cylinder (compare: chosen from the data when not given, the Python "
                   "API requires it; variogram, aggregate: the d of the compare run that wrote RESULT, which a "
                   "compare output does not record: recorded in the error model, checked against it)"),
    Parameter("max_depth", "--max-depth", Real(), label='Max depth (cylinder half-length)', section="3.1.3", engine=same("max_depth"), default=None,
              cloudcompare_keys=("SearchDepth",), py4dgeo="max_distance",
              help="half-length of the cylinder along the normal, on each side (m3c2 compare chooses it from the "
                   "data when not given; the Python API requires it)"),
    Parameter("depth_search", "--depth-search", Choice(*DEPTH_SEARCHES), label='Depth search', section="3.1.3, 5.3",
              engine=enum("depth_search"), cloudcompare="progressive", cli_type=str,
              cloudcompare_keys=("UseSinglePass4Depth",),
              help="how the cylinder's length is searched; two-pass when --first-pass-depth is given"),
    Parameter("first_pass_depth", "--first-pass-depth", Real(), label='First-pass depth', section="5.3",
              engine=unset_is_zero("first_pass_depth"), needs=(TWO_PASS,),
              help="two-pass depth search: a short half-length first, --max-depth only where it finds nothing"),
    Parameter("positive_search_only", "--positive-search-only", Flag(), label='Search along +normal only', section="3.1.3",
              engine=same("positive_search_only"), cli_type=None, cloudcompare_keys=("PositiveSearchOnly",),
              help="search only along +normal (CloudCompare option)"),
    Parameter("median", "--median", Flag(), label='Median and IQR (instead of mean and standard deviation)', section="3.1.3", engine=STATISTIC, cli_type=None,
              cloudcompare_keys=("UseMedian",), py4dgeo="robust_aggr",
              help="median and IQR instead of mean and standard deviation"),
    Parameter("variance", "--variance", Choice("sample", "population"), label='Variance denominator', section="3.3",
              engine=same("variance"), cloudcompare="population", cli_type=str, commands=BOTH, needs=(A_VARIANCE,),
              help="denominator of every variance: n - 1 (sample, as py4dgeo) or n (population, as CloudCompare)"),
    # Confidence (section 3.3, Appendix B)
    Parameter("registration_error", "--registration-error", RealOrRegistration(), label='Registration error (reg of eq. 1)', section="3.3 eq. (1)",
              engine=same("registration_error"), cloudcompare_keys=("RegistrationError", "RegistrationErrorEnabled"),
              py4dgeo="registration_error", cli_type=str, metavar="REG|T.json",
              help="reg of eq. (1), in the clouds' unit, or m3c2 register's T.json (its registration_error)"),
    Parameter("confidence", "--confidence", Real(0.0, below=1.0), label='Confidence level of the LOD', section="3.3",
              engine=same("confidence"), help="confidence level of the LOD"),
    Parameter("min_points", "--min-points", COUNT, label='Fewest points per cylinder for a LOD', section="5.2.1", engine=same("min_points"), cloudcompare=5,
              cli_type=int, cloudcompare_keys=("MinPoints4Stat", "UseMinPoints4Stat"),
              help="points needed in each cylinder for a LOD"),
    # The default from the no-change calibration (docs/validation.md, "Calibration of the LOD"):
    # auto is calibrated at every n where z flags 9 % at n = 5; the peers (CloudCompare, py4dgeo) use z.
    Parameter("lod", "--lod", Choice("z", "t", "auto", "bootstrap"), label='LOD statistic', section="3.3, Appendix B",
              engine=enum("lod"), default="auto", cloudcompare="z", cli_type=str,
              help="the LOD's statistic: eq. (1) with z, with Welch's t (eq. 2), the paper's rule auto (t when "
                   "n1 or n2 < 30), or the bootstrap of Appendix B (--bootstrap N resamples)"),
    Parameter("median_lod", "--median-lod", Choice("maritz-jarrett", "cloudcompare"), label="Median's LOD", section="3.3, Appendix B",
              engine=enum("median_lod"), cloudcompare="cloudcompare", cli_type=str, needs=(PARAMETRIC_MEDIAN,),
              help="with --median: the median's standard error in eq. (1), exact (Maritz-Jarrett) or "
                   "CloudCompare's IQR / 1.349 as if it were a mean's spread"),
    Parameter("t_statistic", "--t-statistic", Flag(), label='Welch t when a cylinder has under 30 points', section="3.3 eq. (2)", default=False, cli_type=None,
              scope="alias", needs=(WELCH_T,), help="the same as --lod auto: Welch t instead of z when n1 or n2 < 30 (eq. 2)"),
    Parameter("bootstrap", "--bootstrap", Integer(0, engine.MAX_BOOTSTRAP_SAMPLES, "0 (off) or >= 2 resamples",
                                                 excluded=(1,)),
              label='Bootstrap resamples', section="Appendix B", engine=same("bootstrap_samples"), cli_type=int,
              help="LOD from N bootstrap resamples (implies --lod bootstrap)"),
    Parameter("seed", "--seed", Integer(0, UINT64_MAX, "a non-negative integer"), label='Bootstrap seed', section="Appendix B",
              engine=same("bootstrap_seed"), cli_type=int, needs=(BOOTSTRAP,), help="bootstrap seed"),
    Parameter("error_model", "--error-model", Text("an error model file"), label='Correlated-error model (m3c2 variogram)', section="docs/algorithm.md",
              engine=ERROR_MODEL, default=None, cli_type=str, metavar="MODEL.json", needs=(EQ1,),
              help="spatially correlated errors (m3c2 variogram's MODEL.json): the LOD is z sqrt(s1^2/n1 + "
                   "s2^2/n2 + sigma_c^2) + reg, sigma_c^2 the model's excess variance (stable distances' total "
                   "sill minus their mean s1^2/n1 + s2^2/n2) at its d, which must be the run's --projection-scale"),
    # False-discovery control over every core point's p_value (m3c2kit.run.fdr; docs/algorithm.md)
    Parameter("fdr", "--fdr", Real(0.0, below=1.0), label='False-discovery level Q', section="docs/algorithm.md", default=None, metavar="Q",
              scope="run",
              help="false-discovery control at level Q over the p_value of every core point: adds q_value (the "
                   "adjusted p-value) and significant_fdr (q_value <= Q); at most a share Q of the core points it "
                   "flags are expected to be false (Benjamini & Hochberg 1995)"),
    Parameter("fdr_method", "--fdr-method", Choice("bh", "by"), label='False-discovery procedure', section="docs/algorithm.md", default="bh",
              cli_type=str, scope="run", needs=(FDR,),
              help="--fdr's procedure: Benjamini-Hochberg (bh: independent or positively dependent p-values) or "
                   "Benjamini-Yekutieli (by: any dependence, BH at Q / sum_{i<=m} 1/i)"),
    # Per-point uncertainty (section 6.2; include/m3c2/uncertainty.hpp)
    Parameter("uncertainty", "--uncertainty", Choice("eq1", "pm", "ep"), label='Uncertainty model', section="6.2", engine=enum("uncertainty"),
              cli_type=str, cloudcompare_keys=("UsePrecisionMaps",), help="the LOD's uncertainty model: eq. (1), M3C2-PM (precision maps) or M3C2-EP "
                                 "(error propagation); pm and ep need their per-point inputs"),
    Parameter("precision_rule", "--precision-rule", Choice("nearest", "all"), label='M3C2-PM precision rule', section="6.2",
              engine=enum("precision_rule"), cli_type=str, needs=(PM,),
              help="M3C2-PM: the precision of the point nearest the cylinder's centre (CloudCompare's) or of "
                   "every point in it"),
    Parameter("precision_scales", "--precision-scales", Positives(2), label='M3C2-PM precision scales', section="6.2", engine=PRECISION_SCALES,
              cli_type=str, cloudcompare_keys=("PM1Scale", "PM2Scale"), metavar="S1,S2", needs=(PM,), help="M3C2-PM: scale of each cloud's precisions"),
    Parameter("ep_covariance", "--ep-covariance", Choice("independent", "mean-of-points", "empirical"), label='M3C2-EP centre covariance', section="6.2",
              engine=enum("ep_covariance"), cli_type=str, needs=(EP,), help="M3C2-EP: the covariance of a centre of gravity"),
    Parameter("ep_lod", "--ep-lod", Choice("projected", "published"), label='M3C2-EP level of detection', section="6.2", engine=enum("ep_lod"),
              cli_type=str, needs=(EP,), help="M3C2-EP: the level of detection, projected on the normal or as published"),
    Parameter("ep_weights", "--ep-weights", Choice("normal", "matrix"), label='M3C2-EP weights', section="6.2", engine=enum("ep_weights"),
              cli_type=str, needs=(EP, WEIGHTED_CENTRES), help="M3C2-EP: the weights of the centres of gravity"),
    # The per-point inputs of pm and ep (read by m3c2kit.run.uncertainty_inputs; in-memory runs)
    Parameter("precision_fields", "--precision-fields", Text("three field names SX,SY,SZ"), label='M3C2-PM precision fields', section="6.2",
              default="sx,sy,sz", cli_type=str, metavar="SX,SY,SZ", scope="run", needs=(PM,),
              help="M3C2-PM: each cloud's fields holding the precisions sx, sy, sz (LAS extra bytes, PLY "
                   "properties, ASCII columns)"),
    Parameter("scan_positions", "--scan-positions", Text("a file, or FILE1,FILE2"), label='M3C2-EP scan positions', section="6.2", default=None,
              cli_type=str, metavar="FILE[,FILE2]", scope="run", needs=(EP,),
              help="M3C2-EP: scan positions (py4dgeo's sps.json or a CSV: id, origin, sigma_range, sigma_scan, "
                   "sigma_yaw[, sigma_range_ppm]); a second file for the compared epoch; an entry without an "
                   "origin takes the E57 scan's pose"),
    Parameter("scan_position_field", "--scan-position-field", Text("a field name"), label='M3C2-EP scan position field', section="6.2",
              default="point_source_id", cli_type=str, metavar="NAME", scope="run", needs=(EP,),
              help="M3C2-EP: the field holding each point's scan-position id (LAS point source id, an extra "
                   "dimension, or scan_index for E57)"),
    Parameter("transform", "--transform", Text("m3c2 register's T.json, or a file (3x4)"), label="Transformation (m3c2 register's T.json, or EP's 3x4)", section="6.2",
              default=None, cli_type=str, metavar="FILE", scope="run", needs=(EP_OR_REGISTRATION,),
              help="m3c2 register's T.json: the compared cloud moved onto the reference before comparing "
                   "(M3C2-EP: as its tfM); M3C2-EP: also the compared epoch's 3x4 transformation tfM (a "
                   "text file), applied to it about the reduction point unless --transform-applied"),
    Parameter("transform_applied", "--transform-applied", Flag(), label='Transformation already applied', section="6.2", default=False, cli_type=None,
              scope="run", needs=(EP, TRANSFORM), help="M3C2-EP: the compared cloud is given already transformed by --transform"),
    Parameter("alignment_covariance", "--alignment-covariance", Text("a file (12x12) or T.json"), label='Alignment covariance', section="6.2",
              default=None, cli_type=str, metavar="FILE", scope="run", needs=(EP,),
              help="M3C2-EP: 12x12 covariance Cxx of the transformation's parameters (r11..r33, tx, ty, tz), "
                   "or m3c2 register's T.json (its 6x6 covariance converted at the reduction point)"),
    Parameter("reduction_point", "--reduction-point", Text("X,Y,Z or a file"), label='Reduction point', section="6.2", default=None,
              cli_type=str, metavar="X,Y,Z", scope="run", needs=(EP, MOVED_OR_PROPAGATED),
              help="M3C2-EP: the point the transformation rotates about (default 0,0,0)"),
    # Vegetation removal before comparing (4.3; CANUPO: m3c2kit.classify, docs/classify.md)
    Parameter("classifier", "--classifier", Text("a classifier file"), label='CANUPO classifier (vegetation removal)', section="4.3", default=None, cli_type=str,
              metavar="FILE", scope="run",
              help="CANUPO classifier (m3c2 classify train, or qCANUPO's .prm): both clouds are classified and "
                   "only the points of the --keep classes compared"),
    Parameter("keep", "--keep", Text("class labels, comma separated"), label='Classes kept', section="4.3", default=None, cli_type=str,
              metavar="CLASS[,CLASS]", scope="run",
              help="with --classifier: the classes kept in both clouds (e.g. ground)"),
    # How the run is made (not what the engine computes)
    Parameter("core_spacing", "--core-spacing", Real(), label='Core point spacing', section="3.1.1", default=None,
              cloudcompare_keys=("SubsampleRadius", "SubsampleEnabled"), scope="run",
              help="core points = the reference subsampled to this minimum spacing"),
    Parameter("threads", "--threads", Integer(0, engine.THREADS_MAX, "0 (all) or a positive integer"), label='Threads', section="-",
              default=0, cli_type=int, cloudcompare_keys=("MaxThreadCount",), commands=BOTH, scope="run",
              help="threads (the computation and LAZ decoding and encoding), 0 for all; results are identical "
                   "for any count"),
    Parameter("compat", "--compat", Choice("cloudcompare"), label='Compatibility', section="-", default=None, cli_type=str, scope="run",
              help="CloudCompare qM3C2 semantics: its defaults where marked (docs/validation.md)"),
    Parameter("position", "--position", Choice("core", "reference", "compared", "reference-or-core",
                                               "compared-or-core"), label='Where output rows are placed', section="3.1.3",
              default="core", cli_type=str, cloudcompare_keys=("ProjDestIndex",), scope="output",
              help="where output rows are placed: the core points or their projection on a cloud (NaN "
                   "coordinates where there is none, the status says why; *-or-core: the core point there)"),
    Parameter("field_names", "--field-names", Choice("m3c2", "cloudcompare", "pdal"), label='Output column names', section="-", default="m3c2",
              cli_type=str, scope="output",
              help="output column names: m3c2kit's, CloudCompare's scalar fields (M3C2 distance, distance "
                   "uncertainty, ...) or PDAL's m3c2_* (table in docs/python.md)"),
    Parameter("float64", "--float64", Flag(), label='Store values as float64', section="-", default=False, cli_type=None, scope="output",
              help="store measured values as float64 (default: float32, relative error 6e-8, < 0.06 mm below "
                   "1 km; in LAS/LAZ integers at 0.1 mm, at most 0.05 mm off, NaN kept)"),
    Parameter("all_fields", "--all-fields", Flag(), label='LAS: every column', section="-", default=False, cli_type=None, scope="output",
              help="LAS/LAZ: also write sigma1, sigma2, the normal (nx, ny, nz), normal_scale, roughness "
                   "and spread1, spread2 (otherwise only distance, lod, significant, n1, n2 and status, as "
                   "CloudCompare; text and PLY files have every column)"),
    # The series steps' options (smooth, kalman, tam3c2, objects, changepoints; the store's layout)
    *SERIES_ROWS,
    # m3c2 pbm3c2's options (the segments, their pairs)
    *PBM3C2_ROWS,
    # m3c2 register's options (the ICP's pairs and steps, --auto-stable's rounds)
    *REGISTRATION_ROWS,
)


def by_name() -> dict[str, Parameter]:
    return {p.name: p for p in PARAMETERS}


def parameters_of(command: str) -> tuple[Parameter, ...]:
    return tuple(p for p in PARAMETERS if command in p.commands)


def by_cloudcompare_key() -> dict[str, Parameter]:
    """The parameter each CloudCompare params-file key sets."""
    return {key: p for p in PARAMETERS for key in p.cloudcompare_keys}
