"""Parsing and checking of the user-facing parameter values shared by the command line, the
Python API and the params file: each parser takes (option name, value) and returns the checked
value or raises a UsageError naming the option. The typed parsers describe their range for the
docs' option table (m3c2kit.settings.docs).

D (``normal_scale``) and d (``projection_scale``) are DIAMETERS, as in Lague et al. (2013) and
CloudCompare; ``max_depth`` is the cylinder's half-length along the normal.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .. import engine
from ..base.errors import UsageError

AXES = {"+x": (1.0, 0.0, 0.0), "-x": (-1.0, 0.0, 0.0), "+y": (0.0, 1.0, 0.0),
        "-y": (0.0, -1.0, 0.0), "+z": (0.0, 0.0, 1.0), "-z": (0.0, 0.0, -1.0)}


def positive(name: str, value) -> float:
    """`value` as a finite float > 0, or a UsageError naming the option."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise UsageError(f"{name} must be a number, got {value!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise UsageError(f"{name} must be finite and > 0, got {value!r}")
    return v


def non_negative(name: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise UsageError(f"{name} must be a number, got {value!r}") from None
    if not (math.isfinite(v) and v >= 0):
        raise UsageError(f"{name} must be finite and >= 0, got {value!r}")
    return v


MAX_SCALES = 1000


def scale_range(minimum: float, maximum: float, step: float) -> list[float]:
    """Diameters minimum, minimum + step, ... up to maximum INCLUDED. Each is minimum + k * step,
    not a running sum, and maximum gets a 1e-9 relative slack: CloudCompare accumulates
    (scale += step) and so can silently drop its largest scale (0.1:0.3:0.1 gives two there).
    Raises ValueError for an empty or oversized range."""
    if maximum < minimum:
        raise ValueError(f"the largest scale {maximum!r} is below the smallest {minimum!r}")
    if not step > 0:  # a step of 0 (a parameter file's NormalStep=0) would divide by zero
        raise ValueError(f"the step must be > 0, got {step!r}")
    limit = maximum + 1e-9 * maximum
    steps = (limit - minimum) / step  # inf for a tiny step over a huge span: math.floor(inf) would raise
    if not steps < MAX_SCALES:
        shown = f"{math.floor(steps) + 1}" if math.isfinite(steps) else "too many"
        raise ValueError(f"step {step!r} gives {shown} scales from {minimum!r} to {maximum!r} (at most {MAX_SCALES})")
    count = math.floor(steps) + 1
    return [s for s in (minimum + k * step for k in range(count + 1)) if s <= limit]


def normal_scales(spec, name: str = "--normal-scale") -> list[float]:
    """Diameters from '2', '0.5,1,2', 'MIN:MAX:STEP' (MAX included), a number or a sequence of
    numbers; errors name the option `name`."""
    if isinstance(spec, (int, float, np.floating, np.integer)):
        return [positive(name, spec)]
    if isinstance(spec, str):
        text = spec.strip()
        if ":" in text:
            parts = text.split(":")
            if len(parts) != 3:
                raise UsageError(f"{name} range must be MIN:MAX:STEP, got {spec!r}")
            lo, hi, step = (positive(name, p) for p in parts)
            try:
                return scale_range(lo, hi, step)
            except ValueError as e:
                raise UsageError(f"{name} range {spec!r}: {e}") from None
        return [positive(name, p) for p in text.split(",") if p.strip()] or _empty(name)
    if isinstance(spec, Sequence) or isinstance(spec, np.ndarray):
        return [positive(name, p) for p in spec] or _empty(name)
    raise UsageError(f"{name} must be a number, a list or MIN:MAX:STEP, got {spec!r}")


def _empty(name: str):
    raise UsageError(f"{name} is empty")


UINT32_MAX = engine.COUNT_MAX
UINT64_MAX = 2**64 - 1


def integer(name: str, value, lo: int, hi: int, rule: str) -> int:
    """`value` as an int in [lo, hi] (the engine's field width), or a UsageError naming the option."""
    try:
        v = int(value)
        # An int, or a text int() read (it refuses "1.5"), is exact as it is (float() would round
        # 2**64 - 1 up and call a 30-digit count inexact); other values must be whole.
        exact = isinstance(value, (int, np.integer, str)) or v == float(value)
    except (TypeError, ValueError, OverflowError):
        raise UsageError(f"{name} must be {rule}, got {value!r}") from None
    if not exact or not lo <= v <= hi:
        if exact and v > hi:
            rule = f"{rule}, at most {hi}"
        raise UsageError(f"{name} must be {rule}, got {value!r}")
    return v


class Integer:
    """An integer in [lo, hi], except the values in `excluded`; `rule` says it in words."""

    def __init__(self, lo: int, hi: int, rule: str, excluded: tuple = ()):
        self.lo, self.hi, self.rule, self.excluded = lo, hi, rule, excluded

    def __call__(self, name: str, value) -> int:
        v = integer(name, value, self.lo, self.hi, self.rule)
        if v in self.excluded:
            raise UsageError(f"{name} must be {self.rule}, got {value!r}")
        return v

    def describe(self) -> str:
        return f"{self.rule}, at most {self.hi}"


class Real:
    """A finite float > lo (or >= lo with `closed`), below `below` when given."""

    def __init__(self, lo: float = 0.0, closed: bool = False, below: float | None = None):
        self.lo, self.closed, self.below = lo, closed, below

    def __call__(self, name: str, value) -> float:
        if self.below is not None:
            return self._interval(name, value)
        return (non_negative if self.closed else positive)(name, value)

    def _interval(self, name: str, value) -> float:
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise UsageError(f"{name} must be a number, got {value!r}") from None
        if not self.lo < v < self.below:
            raise UsageError(f"{name} must be in ({self.lo:g}, {self.below:g}), got {value!r}")
        return v

    def describe(self) -> str:
        if self.below is not None:
            return f"in ({self.lo:g}, {self.below:g})"
        return f"finite, {'>=' if self.closed else '>'} {self.lo:g}"


class RealOrRegistration(Real):
    """A finite float >= 0, or m3c2 register's T.json whose registration_error it takes
    (m3c2kit.io.registration_file: a value ending in .json is a registration file)."""

    def __init__(self):
        super().__init__(closed=True)

    def __call__(self, name: str, value) -> float:
        from ..io.registration_file import is_registration_path, read_registration
        if is_registration_path(value):
            return read_registration(value, name).registration_error
        if isinstance(value, str):  # the command line's text: its messages name the number, as float's
            try:
                value = float(value)
            except ValueError:
                pass
        return super().__call__(name, value)

    def describe(self) -> str:
        return f"{super().describe()}, or m3c2 register's T.json (its registration_error)"


class Choice:
    """One of `values`."""

    def __init__(self, *values: str):
        self.values = values

    def __call__(self, name: str, value) -> str:
        if value not in self.values:
            raise UsageError(f"{name} must be one of {', '.join(self.values)}, got {value!r}")
        return value

    def describe(self) -> str:
        return " | ".join(self.values)


class Positives:
    """`count` finite numbers > 0, as a sequence or 'A,B'."""

    def __init__(self, count: int):
        self.count = count

    def __call__(self, name: str, value) -> list[float]:
        parts = value.split(",") if isinstance(value, str) else list(np.atleast_1d(value))
        if len(parts) != self.count:
            raise UsageError(f"{name} needs {self.count} comma-separated values, got {value!r}")
        return [positive(name, v) for v in parts]

    def describe(self) -> str:
        return f"{self.count} values > 0, comma-separated"


class Text:
    """A name, a file or a short list, kept as given (its meaning is checked where it is used:
    m3c2kit.run.uncertainty_inputs); `rule` says what it is."""

    def __init__(self, rule: str):
        self.rule = rule

    def __call__(self, name: str, value):
        return value

    def describe(self) -> str:
        return self.rule


class Flag:
    """On or off."""

    def __call__(self, name: str, value) -> bool:
        return bool(value)

    def describe(self) -> str:
        return "on / off"


class Scales:
    """Diameters: one value, a list or MIN:MAX:STEP (:func:`normal_scales`)."""

    def __call__(self, name: str, value) -> list[float]:
        return normal_scales(value, name)

    def describe(self) -> str:
        return f"> 0; D, list or MIN:MAX:STEP (at most {MAX_SCALES})"


class Orientation:
    """An axis, a point, a file of points, origin, barycentre, sensor, away:POINT or an array
    (m3c2kit.settings.orientation); kept as given (a file is read, the barycentre taken, when
    the engine parameters are built)."""

    def __call__(self, name: str, value):
        return value

    def describe(self) -> str:
        return "+x -x +y -y +z -z, X,Y,Z, FILE, origin, barycentre, sensor, away:POINT"


class Numbers:
    """Comma-separated finite numbers, at least one, each > 0 and, with `at_most`, <= it (a
    series step's lists: TAM3C2's window ratios and radii, 4D-OBC's DTW thresholds). An empty
    item ("0.2,,0.3") is a typo, not a value to drop."""

    def __init__(self, at_most: float | None = None):
        self.at_most = at_most

    def __call__(self, name: str, value) -> list[float]:
        items = value.split(",") if isinstance(value, str) else list(np.atleast_1d(value))
        try:
            values = [float(v) for v in items]
        except (TypeError, ValueError):
            raise UsageError(f"{name} must be a list of numbers like 0.1,0.2, got {value!r}") from None
        top = math.inf if self.at_most is None else self.at_most
        if not values or not all(0 < v <= top and math.isfinite(v) for v in values):
            raise UsageError(f"{name} must be {self.describe()}, at least one, got {value!r}")
        return values

    def describe(self) -> str:
        inside = "> 0" if self.at_most is None else f"in (0, {self.at_most:g}]"
        return f"numbers {inside}, comma-separated"


class AutoOr:
    """'auto' (the step estimates it) or a value of `kind`."""

    def __init__(self, kind):
        self.kind = kind

    def __call__(self, name: str, value):
        return value if value == "auto" else self.kind(name, value)

    def describe(self) -> str:
        return f"auto, or {self.kind.describe()}"
