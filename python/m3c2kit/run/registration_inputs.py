"""What `m3c2 compare` takes from a registration file (m3c2 register's JSON, read once by
m3c2kit.io.registration_file): ``--transform T.json`` moves the compared cloud onto the reference
before comparing (any uncertainty model; M3C2-EP gets it as its tfM about the reduction point),
and ``--alignment-covariance T.json`` becomes M3C2-EP's 12x12 covariance of (r11..r33, tx, ty, tz)
(docs/registration.md, "From the 6x6 covariance to M3C2-EP's 12x12").

The file's covariance is that of (w, s) in the motion p' = exp([w]x) (M^ p - c) + c + s: the
estimate M^, then a rotation vector w about the centre c (a point of the reference's frame), then
a shift s. EP's parameters at its reduction point red are R = exp([w]x) R^ and
t_red = exp([w]x) (M^ red - c) + c + s - red (p' = R (p - red) + t_red + red). Their Jacobian at
the estimate (w = 0, s = 0): d vec(R) / d w_k = vec([e_k]x R^), d t_red / d w_k = e_k x (M^ red - c),
d t_red / d s = I; the 12x12 is J C J^T (rank 6, positive semidefinite)."""
from __future__ import annotations

import numpy as np

from ..base.errors import UsageError
from ..io.registration_file import Registration, is_registration_path, read_registration

__all__ = ["registration_of", "moves_compared", "moved_compared_cloud", "ep_transform", "ep_jacobian",
           "ep_alignment_covariance", "MovedSource"]


def registration_of(value, option: str) -> Registration | None:
    """The registration file an option names, None when the value is not one (EP's text matrix)."""
    return read_registration(value, option) if is_registration_path(value) else None


def moves_compared(values: dict) -> bool:
    """Whether this run moves the compared cloud itself, before the engine: a registration file
    given to --transform in a run without M3C2-EP (whose engine moves it about the reduction point)."""
    return values.get("uncertainty", "eq1") != "ep" and is_registration_path(values.get("transform"))


def moved_compared_cloud(values: dict, xyz: np.ndarray) -> np.ndarray:
    """The compared points where the run compares them: moved by --transform T.json (moves_compared)."""
    if not moves_compared(values):
        return xyz
    return read_registration(values["transform"], "--transform").moved(xyz)


def ep_transform(reg: Registration, reduction_point) -> np.ndarray:
    """EP's 3x4 [R | t] about the reduction point: p' = R (p - red) + t + red, the file's motion."""
    red = np.asarray(reduction_point, dtype=np.float64)
    r, t = reg.matrix[:3, :3], reg.matrix[:3, 3]
    return np.ascontiguousarray(np.column_stack([r, r @ red + t - red]))


def _cross(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def ep_jacobian(reg: Registration, reduction_point) -> np.ndarray:
    """d (r11..r33, tx, ty, tz) / d (w, s) at the estimate (12x6; module docstring)."""
    red = np.asarray(reduction_point, dtype=np.float64)
    r = reg.matrix[:3, :3]
    arm = r @ red + reg.matrix[:3, 3] - reg.centre
    j = np.zeros((12, 6))
    for k in range(3):
        e = np.eye(3)[k]
        j[:9, k] = (_cross(e) @ r).reshape(9)
        j[9:, k] = np.cross(e, arm)
    j[9:, 3:] = np.eye(3)
    return j


def ep_alignment_covariance(reg: Registration, reduction_point) -> np.ndarray:
    """The file's 6x6 covariance as EP's 12x12 Cxx at the reduction point, exactly symmetric."""
    j = ep_jacobian(reg, reduction_point)
    c = j @ reg.covariance @ j.T
    return np.ascontiguousarray(0.5 * (c + c.T))


class MovedSource:
    """A streamed compared cloud whose points come moved by --transform T.json (moves_compared),
    for a tiled run: each chunk is moved as it is read, so the tiles hold the points where an
    in-memory run compares them (the same motion, Registration.moved, hence the same bits)."""

    def __init__(self, source, values: dict):
        self.source = source
        self.kind = source.kind
        self._registration = read_registration(values["transform"], "--transform")

    def chunks(self, rows: int):
        return (self._registration.moved(xyz) for xyz in self.source.chunks(rows))

    def records(self, rows: int, names):
        return ((self._registration.moved(xyz), fields) for xyz, fields in self.source.records(rows, names))