"""py4dgeo's M3C2EP (py4dgeo 1.2.0's m3c2ep.py, Winiwarter et al. 2021) computed by m3c2kit's
M3C2-EP (``uncertainty="ep"``, docs/algorithm.md §6.5) set to py4dgeo's model: matrix weights,
the mean of the points' covariances, the published (chi-square) level of detection, at least 5
points per cylinder.

Inputs as py4dgeo's: the scan positions of each epoch (``epoch.scanpos_info``, ids counted from
1) and each point's id (``epoch.scanpos_id``); the compared epoch's transformation ``tfM``
(3x4) about ``refPointMov``, its 12x12 covariance ``Cxx``; ``perform_trans=False`` for a compared
epoch already transformed (the measured points are recovered for the error propagation).

Where the numbers differ from py4dgeo's (docs/validation.md §7.3 reproduces each on a minimal
input), py4dgeo's defects are not reproduced:

- the distance is compared - reference, as py4dgeo's own M3C2's; py4dgeo's M3C2EP returns
  reference - compared (the opposite sign);
- ``sigma_scan`` is the error of the vertical angle and ``sigma_yaw`` of the horizontal one;
  py4dgeo swaps them;
- the range error is ``sigma_range`` (plus an optional ``sigma_range_ppm`` entry: sqrt(a^2 +
  (b 1e-6 range)^2)); py4dgeo takes sqrt(a^2 + a 1e-6 range^2), ``sigma_range`` again as a
  distance term;
- the error propagation is at the measured points, where py4dgeo takes the transformed ones;
- a point whose covariance is singular makes its core point not computable (NaN); py4dgeo
  weighs it by the identity;
- every point of a cylinder counts; py4dgeo keeps at most 100,000;
- ``num_samples1`` and ``num_samples2`` are the cylinders' counts wherever they were searched;
  py4dgeo leaves one of them unset (garbage) where a cylinder holds fewer than 5 points.

As in py4dgeo, a core point whose cylinders hold fewer than 5 points has no distance, spread or
covariance (NaN); :attr:`M3C2EP.result` (the full m3c2kit.Result) keeps what m3c2kit measures there.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ...base.errors import UsageError
from ...engine.result import Result
from ...run import uncertainty_inputs as ui
from ...settings import engine_params, resolve
from . import util
from .epoch import Epoch
from .errors import UnsupportedArgument, translated
from .m3c2 import M3C2, uncertainties_of

__all__ = ["M3C2EP", "COVARIANCE_DTYPE"]

#: The dtype of ``M3C2EP.run()``'s covariance: py4dgeo's, each centre of gravity's 3x3 covariance.
COVARIANCE_DTYPE = np.dtype([("cov1", "<f8", (3, 3)), ("cov2", "<f8", (3, 3))])
#: py4dgeo's model in m3c2kit's terms (docs/algorithm.md §6.5; its M3C2Meta "minneigh" is 5).
PY4DGEO_MODEL = {"uncertainty": "ep", "ep_weights": "matrix", "ep_covariance": "mean-of-points",
                 "ep_lod": "published", "min_points": 5}


def _scan_table(epoch: Epoch, which: str) -> np.ndarray:
    """The engine's scan-position table (K, 8) from py4dgeo's scanpos_info: position k (from 1)
    is its entry k - 1; id, origin, sigma_range, sigma_range_ppm (0 if absent), sigma_scan, sigma_yaw."""
    info = getattr(epoch, "scanpos_info", None)
    if not info:
        raise UsageError(f"M3C2EP: the {which} epoch has no scanpos_info (a list of {{'origin': [x, y, z], "
                         "'sigma_range': .., 'sigma_scan': .., 'sigma_yaw': ..}}, one per scan position)")
    rows = []
    for k, entry in enumerate(info, 1):
        try:
            origin = [float(c) for c in entry["origin"]]
            row = [k, *origin, float(entry["sigma_range"]), float(entry.get("sigma_range_ppm", 0.0)),
                   float(entry["sigma_scan"]), float(entry["sigma_yaw"])]
        except KeyError as e:
            raise UsageError(f"M3C2EP: the {which} epoch's scan position {k} has no {e.args[0]!r}") from None
        except (TypeError, ValueError, AttributeError) as e:
            raise UsageError(f"M3C2EP: the {which} epoch's scan position {k} is malformed ({e})") from None
        if len(origin) != 3:
            raise UsageError(f"M3C2EP: the {which} epoch's scan position {k}: origin must have 3 coordinates")
        rows.append(row)
    return np.array(rows, dtype=np.float64)


def _scan_ids(epoch: Epoch, which: str) -> np.ndarray:
    try:
        ids = epoch.scanpos_id
    except (UsageError, AttributeError):
        raise UsageError(f"M3C2EP: the {which} epoch has no scanpos_id (each point's scan position, from 1): set "
                         "epoch.scanpos_id, or read it with read_from_las(..., additional_dimensions="
                         "{'point_source_id': 'scanpos_id'})") from None
    if len(ids) and ids.min() < 0:
        raise UsageError(f"M3C2EP: the {which} epoch's scanpos_id holds a negative id")
    return ids.astype(np.uint32)


def _checked(name: str, check, value) -> np.ndarray:
    """`value` through m3c2kit's check of that input, its message naming py4dgeo's argument."""
    try:
        return check(np.asarray(value, dtype=np.float64))
    except (UsageError, TypeError, ValueError) as e:
        raise UsageError(f"M3C2EP: {name} refused: {e}") from None


class M3C2EP(M3C2):
    """py4dgeo's ``M3C2EP``: M3C2 with error propagation (see the module docstring).

    ``run()`` returns ``(distances, uncertainties, covariance)``: distances (N,) float64,
    compared - reference, NaN where not computed; uncertainties with py4dgeo's fields (``spread1``,
    ``spread2``: the propagated standard deviation of each centre along the normal);
    covariance (:data:`COVARIANCE_DTYPE`) each centre's 3x3 covariance. :attr:`result` then
    holds the full :class:`m3c2kit.Result`. The other arguments are :class:`M3C2`'s.
    """

    @translated
    def __init__(self, tfM: np.ndarray | None = None, Cxx: np.ndarray | None = None,
                 refPointMov: np.ndarray | None = None, perform_trans: bool = True, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.tfM = np.eye(3, 4) if tfM is None else tfM
        self.Cxx = np.zeros((12, 12)) if Cxx is None else Cxx
        self.refPointMov = np.zeros(3) if refPointMov is None else refPointMov
        self.perform_trans = perform_trans
        for name, value, shape in (("tfM", self.tfM, (3, 4)), ("Cxx", self.Cxx, (12, 12)),
                                   ("refPointMov", self.refPointMov, (3,))):
            if np.shape(value) != shape:
                raise UsageError(f"M3C2EP: {name} must have shape {shape}, got {np.shape(value)}")

    @property
    def name(self) -> str:
        return "M3C2EP"

    def _ep_epochs(self) -> tuple[Epoch, Epoch]:
        if self.epochs is None or len(self.epochs) != 2:
            raise UsageError("M3C2EP: epochs must be a pair (reference, compared)")
        for epoch, which in zip(self.epochs, ("reference", "compared")):
            if not isinstance(epoch, Epoch):
                raise UsageError(f"M3C2EP: the {which} epoch must be an Epoch with scanpos_info and scanpos_id, "
                                 f"got {type(epoch).__name__}")
        return self.epochs[0], self.epochs[1]

    def _refuse_what_ep_replaces(self) -> None:
        # py4dgeo's M3C2EP reads neither; m3c2kit refuses them with EP rather than drop them.
        if float(self.registration_error) != 0.0:
            raise UnsupportedArgument("M3C2EP: unsupported py4dgeo argument registration_error: M3C2-EP's alignment "
                                      "covariance Cxx replaces it (py4dgeo's M3C2EP does not read it)")
        if self.robust_aggr:
            raise UnsupportedArgument("M3C2EP: unsupported py4dgeo argument robust_aggr: M3C2-EP's centres are "
                                      "weighted means (py4dgeo's M3C2EP does not read it)")

    @translated
    def run(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(distances, uncertainties, covariance) at the core points, in their order."""
        self._refuse_what_ep_replaces()
        reference, compared = self._ep_epochs()
        core = self._core()
        radius = self._radius()
        # py4dgeo's M3C2EP takes max_distance as it is (its M3C2's rule, at least r, is not applied)
        depth = float(self.max_distance)
        if not depth > 0:
            raise UsageError(f"M3C2EP: max_distance must be a positive number (the cylinder's half-length), got "
                             f"{self.max_distance!r}")
        normals = self._core_normals(core)
        values = resolve({**PY4DGEO_MODEL, "projection_scale": 2.0 * radius, "max_depth": depth,
                          "normal_source": "core", "threads": util.get_num_threads()}, "compare", api=True)
        inputs = ui.EpInputs(_scan_table(reference, "reference"), _scan_table(compared, "compared"),
                             _scan_ids(reference, "reference"), _scan_ids(compared, "compared"),
                             transform=_checked("tfM", ui.transform_matrix, self.tfM),
                             alignment_covariance=_checked("Cxx", ui.alignment_covariance, self.Cxx),
                             reduction_point=_checked("refPointMov", ui.parse_reduction_point, self.refPointMov),
                             transform_applied=not self.perform_trans)
        raw = ui.compute(reference.cloud, compared.cloud, core, engine_params(values, "compare"),
                         core_normals=normals, threads=values["threads"], ep=inputs, covariances=True)
        self.result = Result.from_engine(core, raw, values)
        # py4dgeo measures nothing in a cylinder below its 5 points; m3c2kit reports the distance
        # and the centres (with no LOD: section 3.3), kept in self.result.
        measured = (self.result.n1 >= PY4DGEO_MODEL["min_points"]) & (self.result.n2 >= PY4DGEO_MODEL["min_points"])
        kept = lambda a: np.where(measured.reshape((-1,) + (1,) * (a.ndim - 1)), a, np.nan)  # noqa: E731
        uncertainties = uncertainties_of(self.result)
        uncertainties["spread1"], uncertainties["spread2"] = kept(raw["spread1"]), kept(raw["spread2"])
        covariance = np.empty(len(core), dtype=COVARIANCE_DTYPE)
        covariance["cov1"], covariance["cov2"] = kept(raw["covariance1"]), kept(raw["covariance2"])
        return kept(self.result.distance), uncertainties, covariance
