"""Executing a plan in memory: the clouds are arrays (or m3c2kit.io.Cloud), the run is one task of
the engine (m3c2kit.run.tasks.compute_arrays, the call every tile makes too)."""
from __future__ import annotations

from typing import Callable

from .. import uncertainty_inputs
from ..errors import UsageError
from ..result import Result
from .checks import as_points, check_coordinate_range, check_core_normals, check_spacing
from .cores import core_points_for
from .memory import check_memory
from ..settings import engine_params
from .plan import make_plan
from .tasks import compute_arrays
from .vegetation import filtered_clouds
from .. import engine


def compare(reference, compared, core_points=None, *, core_normals=None,
            progress: Callable[[int, int], object] | None = None, read_points=None, reorder_inputs: bool = False,
            **params):
    """M3C2 in memory; returns (Result, resolved values, (reference, compared) as given): the caller
    emits the data-quality warnings (diagnostics.warn, as m3c2kit.compare does), so that they name its caller's line.
    `reorder_inputs`: the clouds' arrays are the caller's own (m3c2kit.compare)."""
    sensor = getattr(reference if core_points is None else core_points, "scan_positions", None)  # --orient sensor
    plan = make_plan(params, read_points, scan_positions=sensor)
    values = plan.values
    check_core_normals(values, core_normals)
    given = (reference, compared)  # the warnings look at the clouds as given
    reference, compared = filtered_clouds(plan.filter, reference, compared, threads=values["threads"])
    ref = as_points("reference", reference)
    cmp_ = as_points("compared", compared)
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
    raw = compute_arrays(ref, cmp_, core_xyz, plan.engine, normals, threads=values["threads"], progress=progress,
                         per_point=per_point, order_in_place=reorder_inputs)
    result = Result.from_engine(core_xyz, raw, plan.record)
    return result, values, given

