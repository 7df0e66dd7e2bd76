"""The spatially correlated error model of a pair of surveys: a variogram of the M3C2 distance of
stable core points, fitted by ``m3c2 variogram`` and applied by ``m3c2 compare --error-model``
(docs/algorithm.md, "Spatially correlated errors"; Rolstad et al. 2009; Hugonnet et al. 2022).

The model is a nugget (the uncorrelated part) plus a sum of components, each a `sill` (partial
sill, a variance in distance units squared) reached over a `range` (a length, the same units):

- ``spherical``: gamma(h) = sill * (1.5 h/range - 0.5 (h/range)^3) for h < range, sill beyond;
  it reaches its sill exactly AT `range`;
- ``exponential``: gamma(h) = sill * (1 - exp(-3 h/range)); `range` is the PRACTICAL range, where
  95 % of the sill is reached (the convention of xDEM and gstat's "effective range").

The variogram is fitted to core-point distances that are already means over a disc of diameter
d (the run's projection scale), so its sills are variances AT that d: `projection_scale` records
it, and ``compare --error-model`` refuses a run with another d.

The LOD's term is NOT the sum of the partial sills. It is the EXCESS (docs/algorithm.md,
"Spatially correlated errors"): the total variance of a stable core point's distance (the fitted
variogram's total sill, nugget included) minus `mean_u2`, the mean over the same stable core
points of eq. (1)'s own s1^2/n1 + s2^2/n2, which the LOD already counts:
sigma_c^2 = max(0, nugget + sum of sills - mean_u2) (:meth:`ErrorModel.excess_variance`). A
correlation shorter than the core points' spacing lands in the nugget, and is still excess over
eq. (1). The components keep their meaning for the covariance BETWEEN two distinct core points
(:meth:`ErrorModel.covariance`, which ``m3c2 aggregate`` sums).

It lives in the settings layer because compare's parameter ``--error-model`` (settings.table)
reads it; m3c2kit.analysis.error_model is the same module for the variogram toolkit.

The file is JSON: ``{"format": "m3c2kit-error-model", "version": 2, ...}`` with ``mean_u2`` and,
derived from it for the reader, ``excess_variance``; `load` checks every field and raises
:class:`ErrorModelError` (a UsageError) naming the file. Version 1 files (before the excess
estimator: no ``mean_u2``) are read, for their components, with ``mean_u2`` None (so is a
version 2 file whose ``mean_u2`` is null); compare refuses them (:func:`for_compare`), since their sum of partial sills misses the correlation shorter than
the core spacing.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..base.errors import UsageError
from ..io.atomic import atomic_output
from ..io.input_file import read_small_json

__all__ = ["FORMAT", "VERSION", "READS", "KINDS", "LAG_DISTANCES", "Component", "ErrorModel", "ErrorModelError",
           "disc_distance_pdf", "load", "parse", "save", "model_bytes", "for_compare", "label", "RECORDED"]

FORMAT = "m3c2kit-error-model"
VERSION = 2
#: the versions `load` reads (1: no mean_u2, refused by compare)
READS = (1, 2)
KINDS = ("spherical", "exponential")
#: how the lag between two core points is measured: in 3D (cliffs, overhangs) or in plan view
LAG_DISTANCES = ("3d", "2d")
_KIND = "error model file"  # io.input_file.SMALL_FILE_LIMITS' key


class ErrorModelError(UsageError):
    """An error model file that cannot be read or is not valid; the message starts with its path."""


@dataclass(frozen=True)
class Component:
    """One correlated component: its `kind` (KINDS), partial `sill` (variance) and `range` (length;
    the module's docstring gives each kind's convention)."""

    kind: str
    sill: float
    range: float

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"component kind {self.kind!r} is not one of {', '.join(KINDS)}")
        if not (math.isfinite(self.sill) and self.sill >= 0):
            raise ValueError(f"component sill {self.sill!r} must be finite and >= 0")
        if not (math.isfinite(self.range) and self.range > 0):
            raise ValueError(f"component range {self.range!r} must be finite and > 0")

    def variogram(self, h) -> np.ndarray:
        """gamma(h) of this component (0 at h = 0, `sill` at infinity): the engine's formula."""
        from ..engine import component_values  # the engine's, their one place; imported when used
        return component_values(self.kind, self.sill, self.range, h, variogram=True)

    def covariance(self, h) -> np.ndarray:
        """C(h) = sill - gamma(h), the engine's formula (the one region sums use)."""
        from ..engine import component_values
        return component_values(self.kind, self.sill, self.range, h)


@dataclass(frozen=True)
class ErrorModel:
    """nugget + sum of components; `projection_scale` the d (diameter) of the result the model was
    fitted on (None: unknown); `lag_distance` "3d" or "2d"; `notes` free text (what was fitted);
    `mean_u2` the mean of eq. (1)'s s1^2/n1 + s2^2/n2 over the stable core points fitted (None:
    unknown, a version 1 file; compare needs it)."""

    nugget: float
    components: tuple[Component, ...]
    projection_scale: float | None = None
    lag_distance: str = "3d"
    notes: str = ""
    #: the empirical variogram the model was fitted to: (lag, semivariance, pairs) per bin, or empty
    empirical: tuple[tuple[float, float, int], ...] = field(default=(), compare=False)
    mean_u2: float | None = None

    def __post_init__(self):
        if not (math.isfinite(self.nugget) and self.nugget >= 0):
            raise ValueError(f"nugget {self.nugget!r} must be finite and >= 0")
        if not all(isinstance(c, Component) for c in self.components):
            raise ValueError("components must be Component objects")
        if self.projection_scale is not None and not (math.isfinite(self.projection_scale)
                                                      and self.projection_scale > 0):
            raise ValueError(f"projection_scale {self.projection_scale!r} must be finite and > 0")
        if self.lag_distance not in LAG_DISTANCES:
            raise ValueError(f"lag_distance {self.lag_distance!r} is not one of {', '.join(LAG_DISTANCES)}")
        if self.mean_u2 is not None and not (math.isfinite(self.mean_u2) and self.mean_u2 >= 0):
            raise ValueError(f"mean_u2 {self.mean_u2!r} must be finite and >= 0")

    def variogram(self, h) -> np.ndarray:
        """gamma(h): the nugget plus every component for h > 0, 0 at h = 0."""
        h = np.asarray(h, dtype=np.float64)
        g = np.where(h != 0, self.nugget, 0.0)
        for c in self.components:
            g = g + c.variogram(h)
        return g

    def covariance(self, h) -> np.ndarray:
        """The covariance of the CORRELATED part only (the nugget excluded): sum of sills - the
        components' variogram."""
        h = np.asarray(h, dtype=np.float64)
        out = np.zeros(h.shape)
        for c in self.components:
            out = out + c.covariance(h)
        return out

    def correlated_variance(self) -> float:
        """The sum of the partial sills: the variance of the part shared between distinct core
        points (covariance(0)). Not the LOD's term: that is :meth:`excess_variance`."""
        return float(sum(c.sill for c in self.components))

    def total_variance(self) -> float:
        """The total sill, nugget + partial sills: the variance of a stable core point's distance."""
        return float(self.nugget + self.correlated_variance())

    def excess_variance(self) -> float:
        """sigma_c^2 of ``compare --error-model``: the total variance of a stable core point's
        distance not explained by eq. (1)'s s1^2/n1 + s2^2/n2, max(0, total sill - mean_u2)
        (docs/algorithm.md, "Spatially correlated errors")."""
        if self.mean_u2 is None:
            raise ValueError("the model has no mean_u2 (a version 1 file): refit it with m3c2 variogram")
        return max(0.0, self.total_variance() - self.mean_u2)

    def disc_mean_variance(self, diameter: float) -> float:
        """Var of the mean of the correlated part over a disc of `diameter`, if the components were
        the covariance of a POINT field: the integral of C(r) times the pdf of the distance between
        two uniform points in the disc (:func:`disc_distance_pdf`). Used by the simulations to
        know the true correlated variance of a cylinder mean (docs/algorithm.md)."""
        if diameter <= 0:
            return self.correlated_variance()
        # Gauss-Legendre on [0, diameter]: the pdf is smooth inside, its endpoints are zeros.
        x, w = np.polynomial.legendre.leggauss(200)
        r = 0.5 * diameter * (x + 1.0)
        return float(np.sum(0.5 * diameter * w * self.covariance(r) * disc_distance_pdf(r, diameter)))

    def to_json(self) -> dict:
        return {"format": FORMAT, "version": VERSION, "nugget": self.nugget,
                "components": [{"kind": c.kind, "sill": c.sill, "range": c.range} for c in self.components],
                "projection_scale": self.projection_scale, "lag_distance": self.lag_distance,
                "notes": self.notes, "mean_u2": self.mean_u2,
                # derived (excess_variance()), written for the reader; load checks it
                "excess_variance": None if self.mean_u2 is None else self.excess_variance(),
                "empirical": [{"lag": a, "semivariance": b, "pairs": n} for a, b, n in self.empirical]}


def disc_distance_pdf(r, diameter: float) -> np.ndarray:
    """The pdf of the distance between two independent uniform points in a disc of `diameter`
    (the classic result: f(r) = (4 r / (pi R^2)) (acos(u) - u sqrt(1 - u^2)), u = r / (2R))."""
    R = 0.5 * diameter
    r = np.asarray(r, dtype=np.float64)
    u = np.clip(r / (2.0 * R), 0.0, 1.0)
    f = 4.0 * r / (math.pi * R * R) * (np.arccos(u) - u * np.sqrt(1.0 - u * u))
    return np.where((r >= 0) & (r <= diameter), f, 0.0)


def model_bytes(model: ErrorModel) -> bytes:
    """The file's bytes."""
    return (json.dumps(model.to_json(), indent=1) + "\n").encode()


def save(path: str | os.PathLike, model: ErrorModel) -> None:
    """Writes `model` as JSON, atomically."""
    path = Path(path)
    data = model_bytes(model)
    try:
        with atomic_output(path) as tmp:
            Path(tmp).write_bytes(data)
    except OSError as e:
        raise ErrorModelError(f"{path}: cannot write the error model: {e.strerror or e}") from None


#: The largest magnitude of a model's numbers (variances in the data's unit squared, lengths in
#: its unit): beyond, the region sums (N^2 sills) and the simulated fields' FFTs overflowed to
#: NaN intervals with exit 0 (hostile round 2: a sill of 1e308), and a range of 1e-300 asked for a
#: grid of 1e300 cells. A standard deviation of 1e50 or a range of 1e-100 is no error model.
LARGEST = 1e100


def _number(path, doc: dict, key: str, *, positive: bool = False, optional: bool = False) -> float | None:
    v = doc.get(key)
    if v is None and optional:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0 \
            or (positive and v <= 0) or v > LARGEST or (positive and v < 1 / LARGEST):
        need = (f"a number from {1 / LARGEST:g} to {LARGEST:g}" if positive else f"a number from 0 to {LARGEST:g}")
        raise ErrorModelError(f"{path}: not a valid error model ({key!r} must be {need}, found {v!r})")
    return float(v)


def load(path: str | os.PathLike) -> ErrorModel:
    """Reads and checks an error model file; ErrorModelError naming the file on any defect."""
    path = Path(path)
    return parse(read_small_json(path, _KIND, error=ErrorModelError), path)


def parse(doc, path) -> ErrorModel:
    """The model of a file's JSON document `doc` (as :meth:`ErrorModel.to_json` writes it, or a
    series store records it), checked as `load` checks a file; `path` names it in messages."""
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise ErrorModelError(f"{path}: not an error model file (no \"format\": \"{FORMAT}\"; "
                              "write one with m3c2 variogram)")
    version = doc.get("version")
    if isinstance(version, bool) or version not in READS:
        raise ErrorModelError(f"{path}: error model version {version!r} is not supported "
                              f"(this m3c2kit reads versions {', '.join(map(str, READS))})")
    nugget = _number(path, doc, "nugget")
    comps = doc.get("components")
    if not isinstance(comps, list) or not comps:
        raise ErrorModelError(f"{path}: not a valid error model ('components' must be a non-empty list)")
    components = []
    for i, c in enumerate(comps):
        if not isinstance(c, dict) or c.get("kind") not in KINDS:
            raise ErrorModelError(f"{path}: not a valid error model (component {i}: 'kind' must be one of "
                                  f"{', '.join(KINDS)})")
        components.append(Component(c["kind"], _number(path, c, "sill"), _number(path, c, "range", positive=True)))
    lag = doc.get("lag_distance", "3d")
    if lag not in LAG_DISTANCES:
        raise ErrorModelError(f"{path}: not a valid error model ('lag_distance' must be one of "
                              f"{', '.join(LAG_DISTANCES)}, found {lag!r})")
    notes = doc.get("notes", "")
    if not isinstance(notes, str):
        raise ErrorModelError(f"{path}: not a valid error model ('notes' must be text)")
    empirical = doc.get("empirical", [])
    rows = []
    if not isinstance(empirical, list):
        raise ErrorModelError(f"{path}: not a valid error model ('empirical' must be a list)")
    for i, e in enumerate(empirical):
        if not isinstance(e, dict):
            raise ErrorModelError(f"{path}: not a valid error model (empirical bin {i} is not an object)")
        pairs = e.get("pairs")
        if isinstance(pairs, bool) or not isinstance(pairs, int) or pairs < 0:
            raise ErrorModelError(f"{path}: not a valid error model (empirical bin {i}: 'pairs' must be "
                                  "an integer >= 0)")
        rows.append((_number(path, e, "lag"), _number(path, e, "semivariance"), pairs))
    mean_u2 = None if version == 1 else _number(path, doc, "mean_u2", optional=True)
    model = ErrorModel(nugget, tuple(components), _number(path, doc, "projection_scale", positive=True, optional=True),
                       lag, notes, tuple(rows), mean_u2)
    if mean_u2 is not None:
        written = _number(path, doc, "excess_variance")
        if abs(written - model.excess_variance()) > 1e-9 * max(model.total_variance(), 1e-300):
            raise ErrorModelError(f"{path}: not a valid error model ('excess_variance' {written!r} is not "
                                  f"max(0, nugget + sills - mean_u2) = {model.excess_variance()!r})")
    return model


#: how messages name a model given as its content (a series store's record) rather than a file
RECORDED = "the store's recorded error model"


def label(value) -> str:
    """The name of `value` (a file, or a recorded model's content) in messages."""
    return RECORDED if isinstance(value, dict) else str(value)


def for_compare(value) -> ErrorModel:
    """The model for ``compare --error-model``: `value` a file (loaded) or a model's content (a
    dict: what a series store records, so that ``series add`` needs no file); refused when it
    lacks mean_u2 (a version 1 file), whose LOD term cannot be formed (docs/algorithm.md)."""
    model = parse(value, RECORDED) if isinstance(value, dict) else load(value)
    if model.mean_u2 is None:
        raise ErrorModelError(f"{label(value)}: the error model has no 'mean_u2' (a version 1 file, or one written "
                              "without it): compare's LOD term is the excess of the stable distances' variance over "
                              "eq. (1)'s s1^2/n1 + s2^2/n2, which needs it; refit the model with m3c2 variogram")
    return model


def check_projection_scale(model: ErrorModel, name: str, d: float | None, *, of: str = "this run's") -> None:
    """The model's sills are the correlated variance of cylinder means at ITS d: another d would
    average the field over another footprint (docs/algorithm.md, "Spatially correlated errors").
    A UsageError naming both when `d` (the run's, or a result's: `of`) differs from the d the
    model records; nothing to check when either is unknown (the callers say so)."""
    fitted = model.projection_scale
    if d is not None and fitted is not None and abs(d - fitted) > 1e-9 * fitted:
        raise UsageError(f"--error-model {name} was fitted at --projection-scale {fitted:g}, {of} is {d:g}: the "
                         f"correlated variance of a cylinder mean depends on d; fit a model on a result of this d "
                         f"(m3c2 variogram)")
