"""The engine call of a run: one task (the whole run in memory, or one tile) computed from its
inputs. A tile's inputs are paths and numbers (picklable, for Dask workers); a cloud's spill holds
float64 xyz rows, or structured records when the cloud carries per-point engine inputs
(m3c2kit.run.uncertainty_inputs.Carried: --uncertainty pm precisions, ep scan-position ids)."""
from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from .. import engine
from ..base.errors import M3C2Error
from ..io.streaming import PointSource

RESULT_KEYS = engine.RESULT_FIELDS


def record_dtype(columns) -> np.dtype | None:
    """The spill record of a cloud carrying `columns` (Carried.column), None for plain xyz."""
    if not columns:
        return None
    return np.dtype([("xyz", np.float64, (3,)), *[tuple(c) for c in columns]])


@dataclass
class CloudInput:
    """Where a tile's points of one cloud come from: a spill file (float64 xyz, or records of
    `columns`) in file order, or a COPC file and the tile's box."""

    spill: str | None = None
    copc: str | None = None
    lo: tuple = ()
    hi: tuple = ()
    drop_nonfinite: bool = False
    columns: list = field(default_factory=list)

    def load(self) -> tuple[np.ndarray, dict]:
        """(xyz, {engine keyword: per-point array}) of the tile's points of this cloud."""
        if self.spill is None:
            return PointSource(self.copc, drop_nonfinite=self.drop_nonfinite).query_box(self.lo, self.hi), {}
        dtype = record_dtype(self.columns)
        if dtype is None:
            if not os.path.exists(self.spill):
                return np.empty((0, 3)), {}
            return np.fromfile(self.spill, dtype=np.float64).reshape(-1, 3), {}
        rows = np.fromfile(self.spill, dtype=dtype) if os.path.exists(self.spill) else np.empty(0, dtype=dtype)
        return (np.ascontiguousarray(rows["xyz"]),
                {c[0]: np.ascontiguousarray(rows[c[0]]) for c in self.columns})


@dataclass
class TileTask:
    """Everything one tile's computation needs, as paths and numbers (picklable)."""

    tile: int
    n_core: int
    core_path: str
    normals_path: str | None
    reference: CloudInput
    compared: CloudInput
    far_point: tuple  # stands in for an empty cloud: farther than the halo from every core point
    #: the compared cloud's stand-in, where the engine moves that cloud (EP's transformation)
    far_point_compared: tuple | None = None
    #: the engine's uncertainty keywords shared by every point (uncertainty_inputs.shared_inputs)
    shared: dict = field(default_factory=dict)
    #: the per-point value of a stand-in point, by engine keyword
    fillers: dict = field(default_factory=dict)


def worker_threads(threads: int) -> int:
    """`threads`, or on a Dask worker (threads <= 0) the worker's own thread count."""
    if threads <= 0:
        try:
            from distributed import get_worker
            return int(get_worker().state.nthreads)
        except Exception:  # noqa: BLE001 - not on a worker
            return 0
    return int(threads)


def compute_arrays(reference: np.ndarray, compared: np.ndarray, core: np.ndarray, params, normals=None, *,
                   threads: int = 0, progress=None, per_point: dict | None = None, shared: dict | None = None,
                   order_in_place: bool = False) -> dict:
    """THE engine call of every run (in memory and each tile): M3C2 at `core` with the uncertainty
    inputs (per-point arrays by engine keyword, and the shared ones). `order_in_place`: the engine
    may order the two clouds' arrays in place during the call (engine.compute)."""
    return engine.compute(reference, compared, core, params, normals, threads=threads, progress=progress,
                          order_in_place=order_in_place, **(per_point or {}), **(shared or {}))


def compute_tile(task: TileTask, params, threads: int = 0) -> dict:
    """Runs the engine on one tile; returns its result arrays (engine's names) plus ``tile``,
    ``n`` and ``core`` (the tile's core points, in core order)."""
    core = np.fromfile(task.core_path, dtype=np.float64).reshape(-1, 3)
    if len(core) != task.n_core:
        raise M3C2Error(f"tile {task.tile}: core spill holds {len(core)} points, expected {task.n_core}")
    normals = None
    if task.normals_path is not None:
        normals = np.fromfile(task.normals_path, dtype=np.float64).reshape(-1, 3)
    clouds, per_point = [], {}
    for cloud_input, far in ((task.reference, task.far_point), (task.compared, task.far_point_compared or task.far_point)):
        pts, carried = cloud_input.load()
        if not len(pts):
            # The engine refuses an empty cloud; one point beyond every core point's reach leaves
            # each result as the whole cloud's (no point there either) and keeps the order.
            pts = np.asarray([far], dtype=np.float64)
            carried = {c[0]: task.fillers[c[0]] for c in cloud_input.columns}
        clouds.append(pts)
        per_point.update(carried)
    raw = compute_arrays(clouds[0], clouds[1], core, params, normals, threads=worker_threads(threads),
                         per_point=per_point, shared=task.shared)
    out = dict(raw)
    out.update(tile=task.tile, n=len(core), core=core, n_reference=len(clouds[0]), n_compared=len(clouds[1]))
    return out


def result_dtype(out: dict) -> np.dtype:
    fields = [("core", np.float64, (3,))]
    for k in RESULT_KEYS + tuple(k for k in engine.OPTIONAL_RESULT_FIELDS if k in out):
        v = np.asarray(out[k])
        fields.append((k, v.dtype, v.shape[1:]) if v.ndim > 1 else (k, v.dtype))
    return np.dtype(fields)


def result_rows(out: dict, dtype: np.dtype) -> np.ndarray:
    rows = np.empty(out["n"], dtype=dtype)
    for k in dtype.names:
        rows[k] = out[k]
    return rows
