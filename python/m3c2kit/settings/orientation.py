"""The values of ``--orient`` (section 3.1.2: normals are oriented, the sign of the distance
depends on it) and how each becomes the engine's ``Orientation`` (direction, points, away).

* ``+x -x +y -y +z -z``: the normal's dot product with that axis is >= 0;
* ``X,Y,Z``, a FILE of points or a (K, 3) array: towards the closest of those points (the
  paper's scanner positions);
* ``origin``: towards (0, 0, 0); ``barycentre`` (or ``barycenter``): towards the core points'
  barycentre; ``sensor``: towards the scanner position(s) of the cloud the core points come from
  (an E57 file's scan poses; the command line reads them, :func:`sensor_points`);
* ``away:`` before any point form (``away:barycentre``, ``away:1,2,3``): away from it instead.

These are CloudCompare's preferred orientations (``ccNormalVectors::Orientation``, the
qM3C2 key ``NormalPreferedOri``): 6 ``+barycenter`` is ``away:barycentre`` (n . (P - G) >= 0),
7 ``-barycenter`` is ``barycentre``, 8 and 9 are ``away:origin`` and ``origin``, 11 and 12
``away:sensor`` and ``sensor``. CloudCompare takes the barycentre of the core points cloud (the
subsampled reference by default), and so does m3c2: it is the core points' exact mean
(:func:`exact_mean`), the same bits however they are chunked or tiled.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Callable, Iterable

import numpy as np

from ..base.errors import UsageError
from .parsers import AXES

__all__ = ["PointOrientation", "orientation", "needs_core_points", "needs_scan_positions", "exact_mean",
           "sensor_points", "scan_positions_of", "for_clouds", "LATER", "AWAY"]

AWAY = "away:"
BARYCENTRE = ("barycentre", "barycenter")
ORIGIN = "origin"
SENSOR = "sensor"
#: What the command line's help says --orient takes.
SPELLINGS = ("+x|-x|+y|-y|+z|-z, X,Y,Z, an existing FILE of points, origin, barycentre or sensor "
             "(away:POINT for away from a point)")

#: `core_points` for a plan made before the core points are known (the tiled executor computes the
#: barycentre once they are, and builds the engine's Params again).
LATER = object()


@dataclass(frozen=True)
class PointOrientation:
    """Orientation towards (or `away` from) the closest of `points` (K, 3), already resolved."""

    points: np.ndarray
    away: bool = False


def _split(spec) -> tuple[bool, object]:
    if isinstance(spec, str) and spec.strip().lower().startswith(AWAY):
        return True, spec.strip()[len(AWAY):].strip()
    return False, spec


def _word(spec) -> str | None:
    away, rest = _split(spec)
    return rest.strip().lower() if isinstance(rest, str) else None


def needs_core_points(spec) -> bool:
    """Whether `spec` orients by the core points' barycentre."""
    return _word(spec) in BARYCENTRE


def needs_scan_positions(spec) -> bool:
    """Whether `spec` orients by the scanner position (``sensor``)."""
    return _word(spec) == SENSOR


def exact_mean(chunks: Iterable[np.ndarray]) -> np.ndarray:
    """Mean of the rows of (M, 3) `chunks`, correctly rounded from their exact sum: each float64 is
    an integer mantissa times a power of two, and the mantissas are summed as integers per
    exponent, so the result does not depend on the order or the chunking of the points."""
    sums: list[dict[int, int]] = [{}, {}, {}]
    n = 0
    for chunk in chunks:
        chunk = np.asarray(chunk, dtype=np.float64).reshape(-1, 3)
        if not np.isfinite(chunk).all():
            raise UsageError("--orient barycentre: the core points hold a non-finite coordinate")
        n += len(chunk)
        for axis in range(3):
            mantissa, exponent = np.frexp(chunk[:, axis])
            whole = (mantissa * 2.0**53).astype(np.int64)  # exact: |mantissa| < 1
            # 27 + 26 bits: an int64 holds the sum of 2**36 of either half without overflow.
            high, low = whole >> 26, whole & ((1 << 26) - 1)
            order = np.argsort(exponent, kind="stable")
            exponent = exponent[order]
            starts = np.flatnonzero(np.r_[True, exponent[1:] != exponent[:-1]]) if len(exponent) else []
            high_sums = np.add.reduceat(high[order], starts) if len(starts) else []
            low_sums = np.add.reduceat(low[order], starts) if len(starts) else []
            for s, h, lo in zip(starts, high_sums, low_sums):
                e = int(exponent[s])
                sums[axis][e] = sums[axis].get(e, 0) + (int(h) << 26) + int(lo)
    if n == 0:
        raise UsageError("--orient barycentre: there are no core points to take the barycentre of")
    mean = []
    for per_exponent in sums:
        total = sum((Fraction(v) * Fraction(2) ** (e - 53) for e, v in per_exponent.items()), Fraction(0))
        mean.append(float(total / n))
    return np.asarray(mean, dtype=np.float64)


def _barycentre(core_points) -> np.ndarray:
    if core_points is LATER:
        return np.zeros(3)  # replaced once the core points are known (see LATER)
    if core_points is None:
        raise UsageError("--orient barycentre needs the core points (give them to the run)")
    chunks = core_points() if callable(core_points) else [core_points]
    return exact_mean(chunks)


def sensor_points(spec, positions, cloud: str, origin: str = "--orient", also: str | None = None) -> PointOrientation:
    """`spec` (``sensor`` or ``away:sensor``) with the scanner `positions` of the file named
    `cloud` (the one the core points come from; `also`: the reference, looked at when `cloud`
    had none); `origin` says where the spec came from (the option, or the params file's key)
    for the message when there is no scanner position."""
    away, _ = _split(spec)
    if positions is None or len(positions) == 0:
        which = f"neither {cloud} (the core points) nor {also} has one" if also else f"{cloud} has none"
        raise UsageError(
            f"{origin} asks for normals oriented {'away from' if away else 'towards'} the sensor position, "
            f"but {which} (only E57 files carry scanner poses); give the scanner position with "
            f"--orient {'away:' if away else ''}X,Y,Z (or --orient FILE of scan positions)")
    return PointOrientation(np.asarray(positions, dtype=np.float64).reshape(-1, 3), away)


def scan_positions_of(reference, core=None):
    """The scanner positions ``sensor`` (and the default) orients towards: those of the cloud the
    core points come from (CloudCompare's rule), else the reference's; None when neither has any.
    The clouds are m3c2kit.io.Cloud (E57 files carry scan poses) or arrays (none)."""
    for cloud in (core, reference):
        positions = getattr(cloud, "scan_positions", None)
        if positions is not None and len(positions):
            return positions
    return None


def for_clouds(spec, reference, core=None, *, reference_name: str, core_name: str | None = None,
               origin: str = "--orient"):
    """`spec` with the scanner positions of clouds read from files resolved (for executors that
    are handed points without their clouds: tiles; and for messages that name the files): not
    given (None) becomes the positions of :func:`scan_positions_of` or ``+z``; ``sensor`` becomes
    them, with an error naming the files when neither has any; other values are unchanged."""
    positions = scan_positions_of(reference, core)
    if spec is None:
        return "+z" if positions is None else PointOrientation(np.asarray(positions, dtype=np.float64).reshape(-1, 3))
    if not needs_scan_positions(spec):
        return spec
    path, also = (core_name, reference_name) if core_name is not None else (reference_name, None)
    return sensor_points(spec, positions, path, origin, also)


def orientation(spec, read_points: Callable | None = None, core_points=None,
                scan_positions=None) -> tuple[tuple[float, float, float], np.ndarray, bool]:
    """(preferred direction, orientation points (K, 3), away) for a value of --orient (module
    docstring). A FILE is read with `read_points(path)`; `core_points` (an (N, 3) array, or a
    callable giving (M, 3) chunks) gives the barycentre; `scan_positions` the sensor. Not given
    (None): towards the scan positions when there are any (:func:`scan_positions_of`), else +z,
    for every caller (the API, the command line, tiles and series alike)."""
    none = np.empty((0, 3))
    if spec is None:
        if scan_positions is not None and len(scan_positions):
            return AXES["+z"], _checked_points(np.asarray(scan_positions, dtype=np.float64).reshape(-1, 3)), False
        return AXES["+z"], none, False
    if isinstance(spec, PointOrientation):
        return AXES["+z"], _checked_points(spec.points), spec.away
    away, rest = _split(spec)
    if isinstance(rest, str):
        key = rest.strip().lower()
        if not key:  # Path("") is ".": it read the working folder ("is a directory")
            raise UsageError(f"--orient is empty: give {SPELLINGS}")
        if key in AXES and not away:
            return AXES[key], none, False
        if key in BARYCENTRE:
            return AXES["+z"], _barycentre(core_points).reshape(1, 3), away
        if key == ORIGIN:
            return AXES["+z"], np.zeros((1, 3)), away
        if key == SENSOR:
            return AXES["+z"], sensor_points(spec, scan_positions, "the core points' cloud").points, away
        parts = key.split(",")
        if len(parts) == 3:
            try:
                point = [float(p) for p in parts]
            except ValueError:
                point = None
            if point is not None:
                if not all(math.isfinite(c) for c in point):
                    raise UsageError(f"--orient point must be finite, got {spec!r}")
                return AXES["+z"], np.asarray([point], dtype=float), away
        path = Path(rest)
        if read_points is not None and os.path.exists(path):  # False, not OSError, for a name too long
            pts = read_points(path)
            return AXES["+z"], _checked_points(pts), away
        if key in AXES:
            raise UsageError(f"--orient {spec!r}: away: goes before a point (X,Y,Z, FILE, origin, barycentre, "
                             f"sensor), not an axis; use {'-' if key[0] == '+' else '+'}{key[1]} instead")
        raise UsageError(f"--orient must be {SPELLINGS}, got {spec!r}")
    return AXES["+z"], _checked_points(spec), False


def _checked_points(spec) -> np.ndarray:
    try:
        arr = np.asarray(spec, dtype=float)
    except (TypeError, ValueError):
        raise UsageError(f"--orient must be {SPELLINGS}, a 3-vector or (K, 3) points, got {spec!r}") from None
    if arr.ndim == 1 and arr.shape == (3,):
        arr = arr.reshape(1, 3)
    if arr.ndim != 2 or arr.shape[1] != 3 or not np.isfinite(arr).all():
        raise UsageError("orient must be an axis name, a point or a finite (K, 3) array of points")
    return arr
