"""`m3c2kit.register`: point-to-plane ICP of the compared cloud onto the reference on stable areas
(docs/registration.md): given as polygons (plan view), or found by excluding what M3C2 finds
significant, round after round. The engine's ICP (include/m3c2/registration.hpp) does the
numbers; this module chooses the points and the scales."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import engine
from ..base.errors import UsageError
from ..io.registration_file import Registration
from ..run.checks import as_points
from ..settings.needs import check_effective
from ..settings.registration_rows import REGISTER
from ..settings.table import by_name, parameters_of

__all__ = ["RegistrationOptions", "register", "stable_in_polygons"]

#: A round of --auto-stable changes the stable set by less than this share of the points: stopped.
SETTLED_SHARE = 1e-3


def _default(row: str):
    """The default of the parameter table's row (settings/registration_rows.py): the engine's or the row's."""
    return by_name()[row].default_for()


@dataclass(frozen=True)
class RegistrationOptions:
    """What m3c2kit.register does (docs/registration.md). Lengths in the clouds' unit. The defaults
    are the parameter table's rows' (settings/registration_rows.py; the engine's where its
    RegistrationParams holds them, include/m3c2/registration.hpp)."""
    normal_scale: float | None = None   # D of the targets' normals; None: m3c2 suggest's rule on the data
    max_distance: float | None = _default("max_distance")  # the farthest pair; None: D
    reject: float = _default("reject")  # residuals beyond this many robust sd from their median dropped
    max_iterations: int = _default("max_iterations")
    max_points: int = _default("max_points")  # compared points paired, at a fixed stride
    rounds: int = _default("rounds")    # auto_stable: the most register-compare rounds
    threads: int = _default("threads")


def stable_in_polygons(points: np.ndarray, polygons) -> np.ndarray:
    """The points inside any of `polygons` (m3c2kit.io.polygons.Polygon, plan view)."""
    from ..io.polygons import region_index
    return region_index(np.ascontiguousarray(points[:, :2]), polygons) >= 0


def _icp(ref: np.ndarray, cmp_: np.ndarray, options: RegistrationOptions, scale: float) -> dict:
    params = {"normal_diameter": scale, "max_distance": options.max_distance or scale, "reject": options.reject,
              "max_iterations": options.max_iterations, "max_points": options.max_points}
    return engine.register_clouds(ref, cmp_, params, threads=options.threads)


def _as_registration(found: dict, details: dict) -> Registration:
    extra = {k: found[k] for k in ("rms", "pairs", "candidates", "iterations", "converged")}
    return Registration(found["matrix"], found["covariance"], found["centre"], float(found["registration_error"]),
                        {**extra, **details})


def _scales(ref: np.ndarray, cmp_: np.ndarray, options: RegistrationOptions, need_cylinder: bool, threads: int):
    """D (given, or suggest's) and, for auto_stable, the d and max depth of its comparisons."""
    if options.normal_scale is not None and not need_cylinder:
        return float(options.normal_scale), None
    import warnings

    from .suggest import suggest
    with warnings.catch_warnings():  # suggest's trial runs warn about their own trial scales
        warnings.simplefilter("ignore")
        found = suggest(ref, cmp_, threads=threads)
    d = found["projection_scale"] if math.isfinite(found["projection_scale"]) else found["D"]
    scale = float(options.normal_scale) if options.normal_scale is not None else float(found["D"])
    return scale, {"normal_scale": scale, "projection_scale": float(d), "max_depth": float(found["depth"]["max_depth"])}


def register(reference, compared, *, stable=None, auto_stable: bool = False, **options) -> Registration:
    """The rigid motion that maps `compared` onto `reference` ((N, 3) arrays or m3c2kit.io.Cloud).

    stable: None (every point), a list of m3c2kit.io.polygons.Polygon (the points inside them, plan
    view) or a pair of boolean masks (reference, compared). auto_stable: iterate (register, compare
    with M3C2 at the data's scales, drop the points within d of a significant core point, register
    again) until the stable set settles or `rounds` rounds. The keywords are RegistrationOptions'.
    Returns the Registration (m3c2kit.io.registration_file) whose details say how it was found."""
    try:
        opts = RegistrationOptions(**options)
    except TypeError as e:
        raise UsageError(f"register: {e}") from None
    if stable is not None and auto_stable:
        raise UsageError("give stable areas or auto_stable, not both")
    # A given option that would change nothing (rounds without auto_stable) is refused (the rows' needs).
    check_effective(parameters_of(REGISTER), {**vars(opts), "auto_stable": auto_stable}, options)
    ref, cmp_ = as_points("reference", reference), as_points("compared", compared)
    if stable is None:
        ref_mask, cmp_mask = np.ones(len(ref), bool), np.ones(len(cmp_), bool)
    elif isinstance(stable, tuple):
        ref_mask, cmp_mask = (np.asarray(m, dtype=bool) for m in stable)
    else:
        ref_mask, cmp_mask = stable_in_polygons(ref, stable), stable_in_polygons(cmp_, stable)
    if len(ref) == 0 or len(cmp_) == 0:
        raise UsageError(f"the {'reference' if len(ref) == 0 else 'compared'} cloud is empty")
    if stable is not None and (not ref_mask.any() or not cmp_mask.any()):
        raise UsageError(f"no point of the {'reference' if not ref_mask.any() else 'compared'} cloud is in the "
                         "stable areas")
    scale, cylinder = _scales(ref[ref_mask], cmp_[cmp_mask], opts, auto_stable, opts.threads)
    found = _icp(np.ascontiguousarray(ref[ref_mask]), np.ascontiguousarray(cmp_[cmp_mask]), opts, scale)
    details = {"normal_scale": scale, "max_distance": opts.max_distance or scale, "reject": opts.reject,
               "stable": "all" if stable is None and not auto_stable else "auto" if auto_stable else "given"}
    rounds = 0
    if auto_stable:
        found, ref_mask, cmp_mask, rounds = _auto_stable(ref, cmp_, found, opts, scale, cylinder)
        details.update(rounds=rounds, projection_scale=cylinder["projection_scale"], max_depth=cylinder["max_depth"])
    details.update(stable_fraction_reference=float(ref_mask.mean()), stable_fraction=float(cmp_mask.mean()))
    return _as_registration(found, details)


def _auto_stable(ref, cmp_, found, opts: RegistrationOptions, scale: float, cylinder: dict):
    """The rounds of auto_stable: each compares the clouds, the compared one moved by the last
    estimate, keeps the points farther than d from every significant core point and registers
    them again. The stable set is recomputed from every point each round (a point dropped while
    the estimate was off comes back once it is not)."""
    from ..run import in_memory
    d = cylinder["projection_scale"]
    core = np.ascontiguousarray(ref[engine.subsample_min_spacing(ref, d / 2)])
    ref_mask = cmp_mask = None
    rounds = 0
    for rounds in range(1, opts.rounds + 1):
        moved = Registration(found["matrix"], found["covariance"], found["centre"], 0.0).moved(cmp_)
        # eq. (1) with reg = this estimate's registration error: a change must exceed what the
        # registration leaves (section 3.3), or every residual misfit would count as change.
        result = in_memory.compare(ref, moved, core, warn=False, threads=opts.threads,
                                   registration_error=float(found["registration_error"]), **cylinder)
        changed = core[np.asarray(result.significant, dtype=bool)]
        if len(changed) == 0:
            new_ref, new_cmp = np.ones(len(ref), bool), np.ones(len(cmp_), bool)
        else:
            new_ref = engine.c2c(changed, ref, threads=opts.threads)["distance"] > d
            new_cmp = engine.c2c(changed, moved, threads=opts.threads)["distance"] > d
        settled = ref_mask is not None and (np.count_nonzero(new_ref != ref_mask) + np.count_nonzero(
            new_cmp != cmp_mask)) <= SETTLED_SHARE * (len(ref) + len(cmp_))
        ref_mask, cmp_mask = new_ref, new_cmp
        if not ref_mask.any() or not cmp_mask.any():
            raise UsageError("--auto-stable: M3C2 finds every point near a significant change: no stable area is "
                             "left to register on; give the stable areas (--stable POLYGONS)")
        found = _icp(np.ascontiguousarray(ref[ref_mask]), np.ascontiguousarray(cmp_[cmp_mask]), opts, scale)
        if settled:
            break
    return found, ref_mask, cmp_mask, rounds
