"""The engine calls of the LOD calibration, in one place (they move to the engine facade once the
parameter table of issue 12 wires `lod` and `median_lod`): a run with the LOD statistic set on
the engine's Params directly."""
from __future__ import annotations

import numpy as np

from .. import _core

#: The LOD statistics of the engine (params.hpp, Lod), in the paper's terms (section 3.3, App. B).
LODS = ("z", "t", "auto", "bootstrap")
STATISTICS = ("mean", "median")


def vertical_params(d: float, max_depth: float, *, statistic: str = "mean", lod: str = "z",
                    confidence: float = 0.95, bootstrap_samples: int = 200, seed: int = 0,
                    median_lod: str = "maritz_jarrett", min_points: int = 4):
    """Params of a run with imposed vertical normals (the paper's calibration, 5.2.2)."""
    p = _core.Params()
    p.normal_source = _core.NormalSource.vertical
    p.projection_diameter = float(d)
    p.max_depth = float(max_depth)
    p.statistic = getattr(_core.Statistic, statistic)
    p.median_lod = getattr(_core.MedianLod, median_lod)
    p.confidence = float(confidence)
    p.min_points = int(min_points)
    p.bootstrap_seed = int(seed)
    p.bootstrap_samples = int(bootstrap_samples) if lod == "bootstrap" else 0
    p.lod = getattr(_core.Lod, lod)
    return p


def run(reference: np.ndarray, compared: np.ndarray, core: np.ndarray, params, threads: int = 0) -> dict:
    """The engine's raw result arrays (name -> array)."""
    return _core.compute(np.ascontiguousarray(reference, float), np.ascontiguousarray(compared, float),
                         np.ascontiguousarray(core, float), params, threads=threads)


def with_lod(params, lod: str, *, statistic: str | None = None, bootstrap_samples: int = 0, seed: int = 0):
    """`params` (engine Params from api.build_params) with its LOD statistic set explicitly."""
    if statistic is not None:
        params.statistic = getattr(_core.Statistic, statistic)
    params.bootstrap_seed = int(seed)
    if lod == "bootstrap":
        params.bootstrap_samples = int(bootstrap_samples)
    params.lod = getattr(_core.Lod, lod)
    return params
