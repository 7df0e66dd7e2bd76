"""The registration file `m3c2 register` writes and `m3c2 compare --transform`,
`--registration-error` and `--alignment-covariance` read (docs/registration.md): one JSON object,
the one reader and writer of it.

``matrix`` (4x4, row-major) maps the COMPARED cloud onto the REFERENCE: p_ref = M[:3, :3] p + M[:3, 3].
``covariance`` (6x6) is that of (rx, ry, rz, tx, ty, tz) = (w, s) in p' = exp([w]x) (M p - c) + c + s:
a small rotation vector w (radians) about ``centre`` c after the estimate M, then a shift s. ``registration_error`` is the
`reg` of eq. (1) (Lague et al. 2013, section 3.3), in the clouds' unit.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..base.errors import UsageError
from .input_file import parse_json, read_small_text

__all__ = ["FORMAT", "REGISTRATION_KIND", "Registration", "registration_bytes", "read_registration",
           "is_registration_path"]

#: The value of the file's "format" member: how a registration file is told from any other JSON.
FORMAT = "m3c2kit registration"
REGISTRATION_KIND = "registration file"
#: The order of the covariance's rows and columns.
PARAMETERS = ("rx", "ry", "rz", "tx", "ty", "tz")


@dataclass(frozen=True)
class Registration:
    """A rigid registration of the compared cloud onto the reference (module docstring)."""
    matrix: np.ndarray            # (4, 4)
    covariance: np.ndarray        # (6, 6)
    centre: np.ndarray            # (3,)
    registration_error: float
    details: dict = field(default_factory=dict)  # rms, pairs, iterations, converged, stable_fraction, ...

    def moved(self, xyz: np.ndarray) -> np.ndarray:
        """The compared points `xyz` ((n, 3)) moved onto the reference."""
        r, t = self.matrix[:3, :3], self.matrix[:3, 3]
        return np.ascontiguousarray(np.asarray(xyz, dtype=np.float64) @ r.T + t)


def registration_bytes(reg: Registration) -> bytes:
    """The file's text: the contract's members first, then the details."""
    doc = {"format": FORMAT, "version": 1,
           "matrix": reg.matrix.tolist(),
           "covariance": reg.covariance.tolist(),
           "covariance_parameters": list(PARAMETERS),
           "centre": reg.centre.tolist(),
           "registration_error": float(reg.registration_error),
           **reg.details}
    return (json.dumps(doc, indent=2, allow_nan=False) + "\n").encode()


def is_registration_path(value) -> bool:
    """Whether an option's value names a registration file: a path ending in .json (EP's own
    --transform and --alignment-covariance files are text matrices)."""
    return isinstance(value, (str, Path)) and str(value).lower().endswith(".json")


def _array(doc: dict, name: str, shape: tuple, where: str) -> np.ndarray:
    try:
        a = np.array(doc[name], dtype=np.float64)
    except KeyError:
        raise UsageError(f"{where}: no {name!r} member: not a registration file written by m3c2 register") from None
    except (TypeError, ValueError, OverflowError):
        raise UsageError(f"{where}: {name!r} is not a numeric array") from None
    if a.shape != shape:
        raise UsageError(f"{where}: {name!r} must be {'x'.join(map(str, shape))}, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise UsageError(f"{where}: {name!r} holds a non-finite value")
    return a


def read_registration(path, option: str) -> Registration:
    """The registration file `path` given to `option`, checked: a UsageError naming both for any
    other file (a JSON of another kind, a missing member, a non-finite or malformed value)."""
    where = f"{option} {path}"
    doc = parse_json(read_small_text(path, REGISTRATION_KIND, label=where), REGISTRATION_KIND, label=where)
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise UsageError(f"{where}: not a registration file (the JSON m3c2 register writes, with \"format\": "
                         f"\"{FORMAT}\")")
    matrix = _array(doc, "matrix", (4, 4), where)
    if not np.array_equal(matrix[3], [0.0, 0.0, 0.0, 1.0]):
        raise UsageError(f"{where}: the matrix's last row must be 0 0 0 1")
    r = matrix[:3, :3]
    if not (np.max(np.abs(r.T @ r - np.eye(3))) <= 1e-9 and np.linalg.det(r) > 0):
        raise UsageError(f"{where}: the matrix's 3x3 part is not a rotation")
    covariance = _array(doc, "covariance", (6, 6), where)
    if not np.array_equal(covariance, covariance.T):
        raise UsageError(f"{where}: the covariance is not symmetric")
    error = _array(doc, "registration_error", (), where)
    if error < 0:
        raise UsageError(f"{where}: registration_error must be >= 0, got {float(error)!r}")
    centre = _array(doc, "centre", (3,), where)
    details = {k: v for k, v in doc.items() if k not in ("matrix", "covariance", "centre", "registration_error")}
    return Registration(matrix, covariance, centre, float(error), details)
