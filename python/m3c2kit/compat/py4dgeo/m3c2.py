"""py4dgeo's M3C2, CloudCompareM3C2 and write_m3c2_results_to_las (py4dgeo 1.2.0's py4dgeo/m3c2.py
and cloudcompare.py) computed by m3c2kit's engine.

As in py4dgeo, ``run()`` takes its normals from ``self.directions()``: the given
``corepoint_normals``, else the multi-scale normals of ``cloud_for_normals`` (the first epoch by
default) turned towards ``orientation_vector`` (any direction) and kept for later runs. A subclass
that overrides ``directions()`` is honoured (issue 43: it was ignored when normal_radii were
given); one that overrides py4dgeo's C++ callbacks (``callback_workingset_finder``,
``callback_distance_calculation``) is refused, since m3c2kit's engine cannot call them."""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ...base.errors import UsageError
from ...engine.result import Result
from ...run.in_memory import compare
from . import util
from .epoch import Epoch, as_epoch
from .normals import direction, oriented_normals
from .errors import Py4DGeoError, UnsupportedArgument, refuse, translated

__all__ = ["M3C2", "CloudCompareM3C2", "write_m3c2_results_to_las", "uncertainties_of", "UNCERTAINTY_DTYPE"]

#: The dtype of ``M3C2.run()``'s uncertainties: py4dgeo's field names and types.
UNCERTAINTY_DTYPE = np.dtype([("lodetection", "<f8"), ("spread1", "<f8"), ("num_samples1", "<i8"),
                              ("spread2", "<f8"), ("num_samples2", "<i8")])

_M3C2_ARGUMENTS = ("epochs", "corepoints", "normal_radii", "cyl_radius", "cyl_radii", "max_distance",
                   "registration_error", "robust_aggr", "orientation_vector", "corepoint_normals",
                   "cloud_for_normals")
#: py4dgeo's hooks into its C++ loop, which m3c2kit's engine does not call.
_CALLBACKS = ("callback_workingset_finder", "callback_distance_calculation")


def _positive(name: str, value: Any) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise UsageError(f"M3C2: {name} must be a positive number, got {value!r}") from None
    if not v > 0 or not np.isfinite(v):
        raise UsageError(f"M3C2: {name} must be a positive number, got {value!r}")
    return v


class M3C2:
    """py4dgeo's ``M3C2`` class computed by m3c2kit (see the package docstring for the mapping).

    ``run()`` returns ``(distances, uncertainties)``: distances (N,) float64, NaN where not
    computed; uncertainties a structured array with py4dgeo's fields ``lodetection``,
    ``spread1``, ``num_samples1``, ``spread2``, ``num_samples2``. :attr:`result` then holds the
    full :class:`m3c2kit.Result` (status codes, significance, roughness, ...).
    """

    @translated
    def __init__(self, epochs: Sequence[Epoch | np.ndarray] | None = None,
                 corepoints: np.ndarray | None = None, normal_radii: Sequence[float] | None = None,
                 cyl_radius: float | None = None, cyl_radii: Sequence[float] | None = None,
                 max_distance: float = 0.0, registration_error: float = 0.0, robust_aggr: bool = False,
                 orientation_vector: Sequence[float] | np.ndarray = (0.0, 0.0, 1.0),
                 corepoint_normals: np.ndarray | None = None,
                 cloud_for_normals: Epoch | np.ndarray | None = None, **unsupported: Any) -> None:
        refuse("M3C2", unsupported, _M3C2_ARGUMENTS)
        if epochs is not None and len(epochs) != 2:  # py4dgeo checks at construction
            raise Py4DGeoError("Exactly two epochs need to be given!")
        self.epochs = epochs
        self.corepoints = corepoints
        self.normal_radii = normal_radii
        self.cyl_radius = cyl_radius
        self.cyl_radii = cyl_radii
        self.max_distance = max_distance
        self.registration_error = registration_error
        self.robust_aggr = robust_aggr
        self.orientation_vector = orientation_vector
        self.corepoint_normals = corepoint_normals
        self.cloud_for_normals = cloud_for_normals
        self._directions_radii: np.ndarray | None = None
        self.result: Result | None = None

    @property
    def name(self) -> str:
        return "M3C2"

    def _radius(self) -> float:
        radius = self.cyl_radius
        if self.cyl_radii is not None:
            radii = list(self.cyl_radii)
            if len(radii) != 1:
                raise UsageError(f"M3C2: cyl_radii must hold exactly one radius, got {radii}")
            if radius is None:
                radius = radii[0]
        if radius is None:
            raise UsageError("M3C2: give the cylinder radius, cyl_radius=r (m3c2kit's projection_scale is 2r)")
        return _positive("cyl_radius", radius)

    def _core(self) -> np.ndarray:
        if self.corepoints is None:
            raise UsageError("M3C2: give corepoints, an (N, 3) array")
        core = np.ascontiguousarray(self.corepoints, dtype=np.float64)
        if core.ndim != 2 or core.shape[1] != 3:
            raise UsageError(f"M3C2: corepoints must be an (N, 3) array, got shape {core.shape}")
        return core

    def _epochs(self) -> tuple[np.ndarray, np.ndarray]:
        if self.epochs is None or len(self.epochs) != 2:
            raise UsageError("M3C2: epochs must be a pair (reference, compared)")
        reference, compared = (as_epoch(e).cloud for e in self.epochs)
        return reference, compared

    @translated
    def directions(self) -> np.ndarray:
        """The normals of the core points (py4dgeo's ``directions``): ``corepoint_normals`` when
        given ((1, 3) or (N, 3)), else computed once from ``cloud_for_normals`` (the first epoch
        by default) at ``normal_radii`` (the most planar scale: section 3.2) and turned towards
        ``orientation_vector`` (n . o >= 0); NaN where no plane could be fitted."""
        core = self._core()
        if self.corepoint_normals is not None:
            normals = np.ascontiguousarray(self.corepoint_normals, dtype=np.float64)
            if normals.ndim != 2 or normals.shape[1] != 3 or normals.shape[0] not in (1, len(core)):
                raise UsageError(f"M3C2: corepoint_normals must be (1, 3) or ({len(core)}, 3), got {normals.shape}")
            self.corepoint_normals = normals
            return normals
        if not self.normal_radii:
            raise UsageError("M3C2: give normal_radii (a list of radii; m3c2kit's normal_scale is 2 x radius)")
        radii = [_positive("normal_radii", r) for r in self.normal_radii]
        source = self.cloud_for_normals if self.cloud_for_normals is not None else self._epochs()[0]
        normals, self._directions_radii = oriented_normals(as_epoch(source).cloud, core, radii,
                                                           direction(self.orientation_vector))
        self.corepoint_normals = normals
        return normals

    @translated
    def directions_radii(self) -> np.ndarray:
        """The normal radius chosen per core point (py4dgeo's; after directions() computed them)."""
        if self._directions_radii is None:
            raise UsageError("M3C2: radii are only available after directions() computed the normals")
        return self._directions_radii

    def callback_workingset_finder(self):
        raise UnsupportedArgument("M3C2: py4dgeo's C++ callbacks are not m3c2kit's: its engine searches the "
                                  "cylinder itself (m3c2kit.compare)")

    callback_distance_calculation = callback_workingset_finder

    def _refuse_overridden_callbacks(self) -> None:
        for name in _CALLBACKS:
            if getattr(type(self), name) is not getattr(M3C2, name):
                raise UnsupportedArgument(
                    f"{type(self).__name__}.{name} overrides py4dgeo's C++ callback, which m3c2kit's engine never "
                    f"calls (its own cylinder search and statistics: m3c2kit.compare(median=..., ...)); run it "
                    f"with py4dgeo itself")

    def _core_normals(self, core: np.ndarray) -> np.ndarray:
        """One normal per core point from ``self.directions()`` (a subclass's own, as in py4dgeo)."""
        normals = np.asarray(self.directions(), dtype=np.float64)
        if normals.ndim != 2 or normals.shape[1] != 3 or normals.shape[0] not in (1, len(core)):
            raise UsageError(f"{type(self).__name__}.directions() must return (1, 3) or ({len(core)}, 3) normals, "
                             f"got shape {normals.shape}")
        return np.ascontiguousarray(np.broadcast_to(normals, core.shape))

    @translated
    def run(self) -> tuple[np.ndarray, np.ndarray]:
        """(distances, uncertainties) at the core points, in their order."""
        self._refuse_overridden_callbacks()
        reference, compared = self._epochs()
        core = self._core()
        normals = self._core_normals(core)
        result = compare(reference, compared, core, **self.compare_settings(), threads=util.get_num_threads(),
                         normal_source="core", core_normals=normals)  # its normals as they are
        self.result = result
        return result.distance, uncertainties_of(result)

    @translated
    def compare_settings(self) -> dict:
        """m3c2kit's compare keywords of this M3C2 but its normals (the time series' store records
        them: segmentation.py): the cylinder of radius r is projection_scale 2r, at least r long
        (as py4dgeo's), py4dgeo's z LOD, and no minimum point count (py4dgeo has none)."""
        radius = self._radius()
        depth = max(float(self.max_distance), radius)  # py4dgeo: the cylinder reaches at least r
        return {"projection_scale": 2.0 * radius, "max_depth": depth,
                "registration_error": float(self.registration_error), "median": bool(self.robust_aggr),
                "min_points": 1, "lod": "z"}


#: CloudCompare's qM3C2 parameter names (lower case) and py4dgeo's (py4dgeo's cloudcompare.py).
#: py4dgeo maps RegistrationError to `reg_error`, which its M3C2 does not take (a TypeError);
#: here it is `registration_error`, as meant.
_CLOUDCOMPARE_NAMES = {"normalscale": "normal_radii", "registrationerror": "registration_error",
                       "searchdepth": "max_distance", "searchscale": "cyl_radius", "usemedian": "robust_aggr"}


class CloudCompareM3C2(M3C2):
    """py4dgeo's ``CloudCompareM3C2``: M3C2 with CloudCompare's parameter names, whose scales
    are DIAMETERS (NormalScale, SearchScale), as in the paper and m3c2kit."""

    @translated
    def __init__(self, **params: Any) -> None:
        # py4dgeo takes the lower-case names; CloudCompare's own spelling (NormalScale) too here
        renamed = {_CLOUDCOMPARE_NAMES.get(k.lower(), k): v for k, v in params.items()}
        if "cyl_radius" in renamed:
            renamed["cyl_radius"] = 0.5 * renamed["cyl_radius"]
        if "normal_radii" in renamed:
            renamed["normal_radii"] = tuple(0.5 * d for d in np.atleast_1d(renamed["normal_radii"]))
        super().__init__(**renamed)


def uncertainties_of(result: Result) -> np.ndarray:
    """py4dgeo's uncertainty array (:data:`UNCERTAINTY_DTYPE`) from an m3c2kit Result."""
    out = np.empty(len(result), dtype=UNCERTAINTY_DTYPE)
    out["lodetection"] = result.lod
    out["spread1"], out["spread2"] = result.sigma1, result.sigma2
    out["num_samples1"], out["num_samples2"] = result.n1, result.n2
    return out


@translated
def write_m3c2_results_to_las(outfilepath, m3c2: M3C2, attribute_dict: dict | None = None) -> None:
    """py4dgeo's ``write_m3c2_results_to_las``: the core points of `m3c2` with the per-point
    arrays of `attribute_dict` (name -> N values, e.g. ``{"distances": d, "lod":
    u["lodetection"]}``) as LAS 1.4 extra dimensions, written whole or not at all (m3c2kit's
    writer: its scale keeps every coordinate within 0.05 mm; py4dgeo fixes 0.25 mm)."""
    from ...io import write_cloud_table
    if Path(outfilepath).suffix.lower() not in (".las", ".laz"):
        raise UsageError(f"write_m3c2_results_to_las: {outfilepath} is no .las or .laz path (it writes LAS)")
    core = np.ascontiguousarray(m3c2.corepoints, dtype=np.float64)
    fields = {}
    for name, values in (attribute_dict or {}).items():
        column = np.asarray(values)
        if column.shape != (len(core),):
            raise UsageError(f"write_m3c2_results_to_las: attribute {name!r} must hold one value per core point "
                             f"({len(core)}), got shape {column.shape}")
        fields[str(name)] = column
    write_cloud_table(outfilepath, core, fields)
