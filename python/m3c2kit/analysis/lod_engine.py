"""The engine runs of the LOD calibration (m3c2kit.analysis.no_change), through the engine facade:
imposed vertical normals and the LOD statistic set field by field."""
from __future__ import annotations

import numpy as np

from .. import engine

#: The LOD statistics of the engine (params.hpp, Lod), in the paper's terms (section 3.3, App. B).
LODS = ("z", "t", "auto", "bootstrap")
STATISTICS = ("mean", "median")


def vertical_params(d: float, max_depth: float, *, statistic: str = "mean", lod: str = "z",
                    confidence: float = 0.95, bootstrap_samples: int = 200, seed: int = 0,
                    median_lod: str = "maritz_jarrett", min_points: int = 4):
    """Params of a run with imposed vertical normals (the paper's calibration, 5.2.2)."""
    return engine.make_params({
        "normal_source": "vertical", "projection_diameter": float(d), "max_depth": float(max_depth),
        "statistic": statistic, "median_lod": median_lod, "confidence": float(confidence),
        "min_points": int(min_points), "bootstrap_seed": int(seed),
        "bootstrap_samples": int(bootstrap_samples) if lod == "bootstrap" else 0, "lod": lod})


def run(reference: np.ndarray, compared: np.ndarray, core: np.ndarray, params, threads: int = 0) -> dict:
    """The engine's raw result arrays (name -> array)."""
    return engine.compute(np.ascontiguousarray(reference, float), np.ascontiguousarray(compared, float),
                          np.ascontiguousarray(core, float), params, threads=threads)
