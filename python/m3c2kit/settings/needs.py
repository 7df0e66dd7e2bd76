"""When a parameter has an effect. A parameter that acts only in some runs (an M3C2-EP input, the
seed of the bootstrap, the second scale's minimum) names its conditions in the parameter table
(:mod:`.table`, ``Parameter.needs``); :func:`check_effective` refuses a parameter given where one
fails, for the API and every command alike (m3c2kit.settings.resolve), so that no option is ever
silently ignored (docs/errors.md, "Options that would change nothing", issue 31)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping

from ..base.errors import UsageError
from ..io.registration_file import is_registration_path

__all__ = ["Needs", "FITTING_SOURCES", "check_effective", "inapplicable"]

#: The normal sources whose normals are fitted to a cloud (vertical and core normals are imposed).
FITTING_SOURCES = ("reference", "compared", "mean", "horizontal")


@dataclass(frozen=True)
class Needs:
    """A condition on the resolved values under which a parameter acts; `only` completes the
    message "FLAG would change nothing in this run: it applies only ..." (what it needs, or why)."""

    holds: Callable[[Mapping], bool]
    only: str


def _source(values: Mapping) -> str:
    return values.get("normal_source") or "reference"  # m3c2 normals always fits its normals


def _uncertainty(values: Mapping) -> str:
    return values.get("uncertainty") or "eq1"


FITTED_NORMALS = Needs(lambda v: _source(v) in FITTING_SOURCES,
                       "when normals are fitted (--normal-source reference, compared, mean or horizontal); "
                       "--normal-source vertical or core and --grid impose them")
SEVERAL_SCALES = Needs(lambda v: len(v.get("normal_scale") or ()) > 1,
                       "with several normal scales (--normal-scale as a list or MIN:MAX:STEP)")
NOT_CORE_NORMALS = Needs(lambda v: _source(v) != "core",
                         "to normals m3c2 makes; --normal-source core uses the given normals as they are")
TWO_PASS = Needs(lambda v: v.get("depth_search") == "two-pass",
                 "with --depth-search two-pass (implied by --first-pass-depth when no --depth-search is given)")
PARAMETRIC_MEDIAN = Needs(lambda v: bool(v.get("median")) and v.get("lod") != "bootstrap" and _uncertainty(v) == "eq1",
                          "with --median and eq. (1)'s LOD (not --lod bootstrap, not --uncertainty pm or ep)")
BOOTSTRAP = Needs(lambda v: v.get("lod") == "bootstrap",
                  "with --lod bootstrap (--bootstrap N), a run's only random step")
WELCH_T = Needs(lambda v: _uncertainty(v) == "eq1" and not (v.get("median") and v.get("median_lod") == "maritz-jarrett"),
                "with eq. (1) of the mean, or of the median with --median-lod cloudcompare: --uncertainty pm and ep "
                "and the Maritz-Jarrett median LOD use z")
PM = Needs(lambda v: _uncertainty(v) == "pm", "with --uncertainty pm (an M3C2-PM input)")
EQ1 = Needs(lambda v: _uncertainty(v) == "eq1",
            "with eq. (1)'s LOD: --uncertainty pm and ep model the correlated errors themselves (counted twice)")
EP = Needs(lambda v: _uncertainty(v) == "ep", "with --uncertainty ep (an M3C2-EP input)")
EP_OR_REGISTRATION = Needs(lambda v: _uncertainty(v) == "ep" or is_registration_path(v.get("transform")),
                           "with m3c2 register's T.json (any run) or with --uncertainty ep (its 3x4 text file)")
WEIGHTED_CENTRES = Needs(lambda v: v.get("ep_covariance") != "empirical",
                         "with --ep-covariance independent or mean-of-points: the empirical covariance takes eq. (1)'s "
                         "centres, not weighted ones")
A_VARIANCE = Needs(lambda v: not v.get("median") or _source(v) in FITTING_SOURCES,
                   "with the mean or fitted normals (their roughness): --median's spread is the IQR")
TRANSFORM = Needs(lambda v: v.get("transform") is not None,
                  "with --transform FILE (the transformation that was applied)")
MOVED_OR_PROPAGATED = Needs(lambda v: v.get("transform") is not None or v.get("alignment_covariance") is not None,
                            "with --transform or --alignment-covariance: it is the point the transformation "
                            "rotates about")


def _given(value) -> bool:
    # None is "not given"; an on/off flag given as False asks for nothing (the default).
    return value is not None and value is not False


def inapplicable(parameters, values: Mapping) -> dict:
    """{name: the first condition it fails} for each parameter whose conditions `values` fail."""
    return {p.name: need for p in parameters for need in p.needs[::-1] if not need.holds(values)}


def check_effective(parameters, values: Mapping, given: Mapping) -> None:
    """A UsageError naming the first given parameter (table order) that a condition of its own
    says would change nothing in this run, with what it needs."""
    moot = inapplicable(parameters, values)
    for p in parameters:
        if p.name in moot and _given(given.get(p.name)):
            raise UsageError(f"{p.flag} would change nothing in this run: it applies only {moot[p.name].only}")
