"""py4dgeo's registration functions (py4dgeo 1.2.0's registration.py) on m3c2kit's point-to-plane
ICP (m3c2kit.register; docs/registration.md).

Each returns a :class:`Transformation` that maps `epoch` onto `reference_epoch`, applied as in
py4dgeo: ``epoch.transform(t)``, x' = A (x - r) + t + r, r its ``reduction_point``.

Where they differ from py4dgeo's (docs/python.md has the table):

- One ICP for all three: point-to-plane (Chen & Medioni 1992). py4dgeo's
  ``iterative_closest_point`` is point-to-point (Besl & McKay 1992), which on a sampled surface
  stops where the two samplings' points, not their surfaces, fit best.
- The planes are m3c2kit's own fit at D = 2 x the radius the reference's normals were computed
  with (``Epoch.calculate_normals(radius)``), or at m3c2 suggest's D when its normals came from
  elsewhere or, for ``iterative_closest_point``, there are none; the values in ``normals`` are
  not read (a plane's orientation does not matter to a point-to-plane residual).
- Pairs: at most D apart (``max_distance``), residuals beyond 3 robust standard deviations
  dropped; py4dgeo pairs every point with its nearest neighbour at any distance and drops none.
- Convergence: the engine's test on the motion (a step moving no point by more than a fixed
  share, RegistrationParams.tolerance, of the compared points' RMS distance to their centre), not
  py4dgeo's on the mean nearest-neighbour distance; a ``tolerance`` other than py4dgeo's default
  is therefore refused (UnsupportedArgument).
- ``reduction_point`` is honoured: A | t is expressed about r, so that ``epoch.transform(t)`` is
  right for any r. py4dgeo 1.2.0 computes its matrix about the origin and returns it with r, so
  that with r != 0 the transformed epoch lands (I - A) r away from its fit.
- ``icp_with_stable_areas`` finds the stable areas with M3C2 (``register(auto_stable=True)``:
  the points near a significant change dropped, round after round), not with py4dgeo's
  supervoxels; its supervoxel arguments have nothing to act on, which a warning says.
"""
from __future__ import annotations

import warnings

import numpy as np

from ... import engine
from ...analysis.registration import register
from ...base.errors import M3C2Warning, UsageError
from ...io.registration_file import Registration
from ...settings.parsers import positive
from . import util
from .epoch import Epoch, as_epoch
from .errors import UnsupportedArgument, translated
from .transformation import Transformation

__all__ = ["Transformation", "iterative_closest_point", "point_to_plane_icp", "icp_with_stable_areas"]

#: py4dgeo's default ``tolerance``: the one value whose meaning m3c2kit's ICP keeps (see above).
PY4DGEO_TOLERANCE = 0.00001
_NO_NORMALS = ("Normals for this {} have not been calculated! Please use Epoch.calculate_normals or load "
               "externally calculated normals.")


def _reduction_point(value, where: str) -> np.ndarray:
    r = np.zeros(3) if value is None else np.asarray(value, dtype=np.float64).ravel()
    if r.shape != (3,) or not np.isfinite(r).all():
        raise UsageError(f"{where}: reduction_point must be 3 finite numbers, got {value!r}")
    return r


def _about(found: Registration, r: np.ndarray) -> Transformation:
    """`found`'s motion p' = R p + t written about r: A | t' with t' = t + R r - r."""
    rotation, shift = found.matrix[:3, :3], found.matrix[:3, 3]
    affine = np.identity(4)
    affine[:3, :3], affine[:3, 3] = rotation, shift + rotation @ r - r
    return Transformation(affine_transformation=affine, reduction_point=r, registration=found)


def _normal_scale(reference: Epoch) -> float | None:
    """D: twice the radius of the reference's calculate_normals, else None (m3c2 suggest's)."""
    radius = getattr(reference, "normals_radius", None)
    return None if radius is None else 2.0 * radius


def _require_normals(epoch, kind: str) -> None:
    # py4dgeo's check and message: its point-to-plane steps read them.
    if getattr(epoch, "normals", None) is None:
        raise UsageError(_NO_NORMALS.format(kind))


def _check_tolerance(where: str, tolerance) -> None:
    if tolerance != PY4DGEO_TOLERANCE:
        relative = engine.default_fields("RegistrationParams")["tolerance"]
        raise UnsupportedArgument(
            f"{where}: unsupported py4dgeo argument tolerance={tolerance!r}: m3c2kit's ICP stops on the motion (a "
            f"step that moves no point by more than {relative:g} of the cloud's RMS radius), not on the change of "
            f"the mean nearest-neighbour distance; leave tolerance at py4dgeo's default {PY4DGEO_TOLERANCE}")


def _iterations(where: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise UsageError(f"{where}: max_iterations must be a positive integer, got {value!r}")
    return int(value)


def _registered(reference_epoch, epoch, reduction_point, where: str, **options) -> Transformation:
    r = _reduction_point(reduction_point, where)
    found = register(as_epoch(reference_epoch).cloud, as_epoch(epoch).cloud, threads=util.get_num_threads(),
                     normal_scale=_normal_scale(reference_epoch), **options)
    return _about(found, r)


@translated
def iterative_closest_point(reference_epoch, epoch, max_iterations=50, tolerance=0.00001,
                            reduction_point=None) -> Transformation:
    """py4dgeo's ``iterative_closest_point``: the motion of `epoch` onto `reference_epoch`, by
    m3c2kit's point-to-plane ICP (py4dgeo's is point-to-point: module docstring)."""
    where = "iterative_closest_point"
    _check_tolerance(where, tolerance)
    return _registered(reference_epoch, epoch, reduction_point, where,
                       max_iterations=_iterations(where, max_iterations))


@translated
def point_to_plane_icp(reference_epoch, epoch, max_iterations=50, tolerance=0.00001,
                       reduction_point=None) -> Transformation:
    """py4dgeo's ``point_to_plane_icp``: the motion of `epoch` onto `reference_epoch`, which must
    have normals, as py4dgeo asks; the planes are fitted at D = 2 x their radius (module docstring)."""
    where = "point_to_plane_icp"
    _require_normals(reference_epoch, "Reference Epoch")
    _check_tolerance(where, tolerance)
    return _registered(reference_epoch, epoch, reduction_point, where,
                       max_iterations=_iterations(where, max_iterations))


@translated
def icp_with_stable_areas(reference_epoch, epoch, initial_distance_threshold, level_of_detection,
                          reference_supervoxel_resolution, supervoxel_resolution, min_svp_num=10,
                          reduction_point=None) -> Transformation:
    """py4dgeo's ``icp_with_stable_areas``: the motion of `epoch` onto `reference_epoch` fitted on
    their stable areas. Both epochs must have normals, as py4dgeo asks. The stable areas are
    m3c2kit's (``m3c2kit.register(auto_stable=True)``: M3C2 at the data's scales, the points near
    a significant change dropped, round after round; docs/registration.md), not py4dgeo's
    supervoxels: ``initial_distance_threshold`` (raised to ``level_of_detection`` when smaller,
    as py4dgeo does) bounds the pairs (``max_distance``); the change threshold is M3C2's level of
    detection at each core point; the supervoxel arguments have nothing to act on (a M3C2Warning
    says so)."""
    where = "icp_with_stable_areas"
    _require_normals(reference_epoch, "Reference Epoch")
    _require_normals(epoch, "Epoch")
    lod = positive(f"{where}: level_of_detection", level_of_detection)
    reach = max(positive(f"{where}: initial_distance_threshold", initial_distance_threshold), lod)
    positive(f"{where}: reference_supervoxel_resolution", reference_supervoxel_resolution)
    positive(f"{where}: supervoxel_resolution", supervoxel_resolution)
    if isinstance(min_svp_num, bool) or not isinstance(min_svp_num, (int, np.integer)) or min_svp_num < 1:
        raise UsageError(f"{where}: min_svp_num must be a positive integer, got {min_svp_num!r}")
    warnings.warn(f"{where}: m3c2kit finds the stable areas with M3C2 (m3c2kit.register(auto_stable=True)), not "
                  "with supervoxels: reference_supervoxel_resolution, supervoxel_resolution and min_svp_num do not "
                  "apply, and a change is what exceeds M3C2's level of detection at each core point "
                  "(level_of_detection only raises initial_distance_threshold, the farthest pair)",
                  M3C2Warning, stacklevel=3)
    return _registered(reference_epoch, epoch, reduction_point, where, auto_stable=True, max_distance=reach)
