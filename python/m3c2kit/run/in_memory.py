"""Executing a plan in memory: the clouds are arrays (or m3c2kit.io.Cloud), the run is one task of
the engine (m3c2kit.run.tasks.compute_arrays, the call every tile makes too). Also the other
computations on arrays: normals and subsampling. m3c2kit.compare (the package's API) is
:func:`compare` with the vegetation filter its keywords ask for."""
from __future__ import annotations

from typing import Callable

import numpy as np

from . import diagnostics, registration_inputs, uncertainty_inputs
from .. import engine
from ..base.errors import UsageError
from ..engine.result import Result
from ..settings import engine_params, orientation, resolve
from ..settings.parsers import positive
from .checks import as_points, check_coordinate_range, check_core_normals, check_moved_range, check_spacing
from .cores import core_points_for
from .fdr import Fdr
from .memory import check_memory
from .plan import make_plan
from .tasks import compute_arrays
from .vegetation import filtered_clouds


def compare(reference, compared, core_points=None, *, core=None, warn: bool = True, stacklevel: int = 2,
            **kwargs) -> Result:
    """M3C2 in memory (m3c2kit.compare's run; keywords as :func:`run`'s), with the run's
    data-quality warnings (m3c2kit.run.diagnostics) emitted as M3C2Warning naming the line
    `stacklevel` frames up (2: the caller's); `warn=False` for runs made to diagnose another one."""
    if core is not None and core_points is not None:
        raise UsageError("give core_points or core (the same parameter), not both")
    result, values, given = run(reference, compared, core if core_points is None else core_points, **kwargs)
    if warn:
        diagnostics.warn(result, values, *(as_points(n, c) for n, c in zip(("reference", "compared"), given)),
                         stacklevel=stacklevel + 1)
    return result


def run(reference, compared, core_points=None, *, core_normals=None, vegetation=None,
        progress: Callable[[int, int], object] | None = None, read_points=None, reorder_inputs: bool = False,
        **params):
    """M3C2 in memory; returns (Result, resolved values, (reference, compared) as given).
    `vegetation`: the --classifier / --keep filter (m3c2kit.classify.vegetation), or None.
    `reorder_inputs`: the clouds' arrays are the caller's own (m3c2kit.compare)."""
    sensor = orientation.scan_positions_of(reference, core_points)  # --orient sensor, and its default
    plan = make_plan(params, read_points, vegetation=vegetation, scan_positions=sensor)
    values = plan.values
    check_core_normals(values, core_normals)
    given = (reference, compared)  # the warnings look at the clouds as given
    reference, compared = filtered_clouds(plan.filter, reference, compared, threads=values["threads"])
    ref = as_points("reference", reference)
    cmp_ = registration_inputs.moved_compared_cloud(values, as_points("compared", compared))  # --transform T.json
    for name, cloud in (("reference", ref), ("compared", cmp_)):
        if len(cloud) == 0:
            raise UsageError(f"the {name} cloud is empty (0 points)")
    core_xyz = core_points_for(ref, core_points, values["core_spacing"])
    if len(core_xyz) == 0:
        raise UsageError("core_points is empty: there is nothing to compute")
    plan.engine = engine_params(values, "compare", read_points, core_points=core_xyz, scan_positions=sensor)
    check_memory(len(ref), len(cmp_), len(core_xyz), params=plan.engine, reorder_inputs=reorder_inputs)
    if values["normal_subsample"] is not None:
        check_spacing("--normal-subsample", values["normal_subsample"], ref, cmp_)
    limit = engine.max_abs_coordinate(plan.engine)
    check_coordinate_range("reference", reference, ref, limit)
    check_coordinate_range("compared", compared, cmp_, limit)

    normals = None
    if values["normal_source"] == "core":
        if core_normals is None:
            raise UsageError("--normal-source core needs core_normals (one normal per core point)")
        normals = as_points("core_normals", core_normals)
        if len(normals) != len(core_xyz):
            raise UsageError(f"core_normals has {len(normals)} rows for {len(core_xyz)} core points")
    # Per-point inputs of --uncertainty pm / ep from the clouds' fields (docs/algorithm.md §6.5).
    per_point = uncertainty_inputs.inputs_for(values, reference, compared)
    check_moved_range(per_point, cmp_, limit)
    raw = compute_arrays(ref, cmp_, core_xyz, plan.engine, normals, threads=values["threads"], progress=progress,
                         per_point=per_point, order_in_place=reorder_inputs)
    result = Result.from_engine(core_xyz, raw, plan.record)
    fdr = Fdr.of(values)
    if fdr is not None:  # --fdr: one ranking of every core point's p-value (m3c2kit.run.fdr)
        fdr.apply(result)
    return result, values, given



def normals(cloud, core_points=None, *, progress=None, read_points=None, **params) -> dict:
    """Normals at the most planar scale (section 3.2, 6.3) of any cloud, oriented, with roughness.
    Keywords: the parameter table's that `m3c2 normals` takes (normal_scale, orient, ...)."""
    values = resolve(params, "normals")
    pts = as_points("cloud", cloud)
    core = pts if core_points is None else as_points("core_points", core_points)
    sensor = orientation.scan_positions_of(cloud, core_points)
    p = engine_params(values, "normals", read_points, core_points=core, scan_positions=sensor)
    out = engine.compute_normals(pts, core, p, threads=values["threads"], progress=progress)
    out["core"] = core
    return out


def subsample(points, spacing: float) -> np.ndarray:
    """Indices of points kept with no two closer than `spacing` (greedy in input order)."""
    pts = as_points("points", points)
    spacing = check_spacing("--spacing", positive("--spacing", spacing), pts)
    return engine.subsample_min_spacing(pts, spacing, "--spacing")
