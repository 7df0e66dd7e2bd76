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
from ..run.checks import as_points
from ..base.errors import UsageError

MODELS = ("none", "plane")
RULES = ("closer", "model")
MODEL_NEIGHBOURS = 6  # the plane's k nearest reference points when no model_radius is given
RULE = "closer"


def c2c(reference, compared, *, model: str = "none", model_radius: float | None = None,
        model_neighbours: int | None = None, rule: str | None = None, threads: int = 0,
        progress=None) -> dict[str, np.ndarray]:
    """Keys: distance (C2C), nearest (index into reference), model_distance (NaN without a
    plane), hf_distance (C2C_HF; = distance where there is no plane), model_count.
    model_neighbours defaults to MODEL_NEIGHBOURS, rule to RULE; both act only with a plane."""
    options = model_options(model, model_radius, model_neighbours, rule)
    ref, cmp_ = as_points("reference", reference), as_points("compared", compared)
    return engine.c2c(ref, cmp_, **options, threads=threads, progress=progress)  # engine checks the integers


def model_options(model: str, model_radius: float | None, model_neighbours: int | None, rule: str | None) -> dict:
    """The engine's model arguments, defaults filled in; UsageError for a bad value and for an
    option that would change nothing (refused, never ignored: docs/errors.md, issue 31 item 5).
    The command line calls it before reading its clouds."""
    if model not in MODELS:
        raise UsageError(f"--model must be one of {', '.join(MODELS)}, got {model!r}")
    if rule is not None and rule not in RULES:
        raise UsageError(f"--rule must be one of {', '.join(RULES)}, got {rule!r}")
    if model_radius is not None and not (np.isfinite(model_radius) and model_radius > 0):
        raise UsageError(f"--model-radius must be finite and > 0, got {model_radius!r}")
    if model == "none":
        for flag, value in (("--model-radius", model_radius), ("--model-knn", model_neighbours), ("--rule", rule)):
            if value is not None:
                raise UsageError(f"{flag} would change nothing in this run: it applies only with --model plane")
    elif model_radius is not None and model_neighbours is not None:
        raise UsageError("--model-knn would change nothing in this run: --model-radius chooses the plane's "
                         "neighbours instead; give one of them")
    return dict(model=model, model_radius=float(model_radius or 0.0),
                model_neighbours=MODEL_NEIGHBOURS if model_neighbours is None else model_neighbours,  # engine checks it
                rule=RULE if rule is None else rule)
