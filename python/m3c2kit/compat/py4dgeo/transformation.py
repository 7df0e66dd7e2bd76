"""py4dgeo's ``Transformation`` (py4dgeo 1.2.0's registration.py): what its registration functions
return and ``Epoch.transform`` applies, x' = A (x - r) + t + r."""
from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

__all__ = ["Transformation"]


@dataclasses.dataclass(frozen=True)
class Transformation:
    """A rigid motion as py4dgeo's: ``affine_transformation`` (4x4, A | t) applied about
    ``reduction_point`` r (3,). ``registration`` is m3c2kit's addition: the registration that
    found it (m3c2kit.io.registration_file.Registration: ``covariance``, ``registration_error``,
    ``details``), None for one made otherwise."""

    affine_transformation: np.ndarray
    reduction_point: np.ndarray
    registration: Any = dataclasses.field(default=None, compare=False, repr=False)
