"""C2C and C2C_HF closest-point baselines (section 3.4, Fig. 4), computed by the C++ engine
(include/m3c2/baselines.hpp).

C2C: distance from each compared point to its nearest reference point (exact, ties to the
lowest index). C2C_HF: the nearest reference point's neighbours (the k nearest, itself included,
or those within model_radius) get a least-squares plane (PCA: centroid and the eigenvector of the
smallest covariance eigenvalue), and the distance to that plane replaces the closest-point one:
with rule 'closer' (CloudCompare >= 2.5, "local model: least-squares plane") the smaller of the two
is kept; with rule 'model' (CloudCompare 2.3, which the paper used) the plane distance always is.
Both are unsigned, as in CloudCompare.
"""
from __future__ import annotations

import numpy as np

from .. import engine
from ..api import as_points
from ..errors import UsageError

MODELS = ("none", "plane")
RULES = ("closer", "model")


def c2c(reference, compared, *, model: str = "none", model_radius: float | None = None, model_neighbours: int = 6,
        rule: str = "closer", threads: int = 0, progress=None) -> dict[str, np.ndarray]:
    """Keys: distance (C2C), nearest (index into reference), model_distance (NaN without a
    plane), hf_distance (C2C_HF; = distance where there is no plane), model_count."""
    if model not in MODELS:
        raise UsageError(f"--model must be one of {', '.join(MODELS)}, got {model!r}")
    if rule not in RULES:
        raise UsageError(f"--rule must be one of {', '.join(RULES)}, got {rule!r}")
    if model_radius is not None and not (np.isfinite(model_radius) and model_radius > 0):
        raise UsageError(f"--model-radius must be finite and > 0, got {model_radius!r}")
    ref, cmp_ = as_points("reference", reference), as_points("compared", compared)
    return engine.c2c(ref, cmp_, model=model, model_radius=float(model_radius or 0.0),
                      model_neighbours=int(model_neighbours), rule=rule, threads=int(threads), progress=progress)
