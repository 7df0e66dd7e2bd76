"""py4dgeo's M3C2 interface on m3c2kit's engine: a py4dgeo script runs by changing its import.

    >>> import m3c2kit.compat.py4dgeo as py4dgeo
    >>> epoch1, epoch2 = py4dgeo.read_from_xyz("t1.xyz", "t2.xyz")
    >>> m3c2 = py4dgeo.M3C2(epochs=(epoch1, epoch2), corepoints=epoch1.cloud[::50],
    ...                     normal_radii=[1.0], cyl_radius=2.0, max_distance=5.0)
    >>> distances, uncertainties = m3c2.run()
    >>> uncertainties["lodetection"]

Translation (docs/python.md has the full table): py4dgeo's radii are half of m3c2kit's
diameters (``normal_radii=[r]`` is ``normal_scale=2r``, ``cyl_radius=r`` is
``projection_scale=2r``); ``max_distance`` is ``max_depth``, raised to ``cyl_radius`` when
smaller, as py4dgeo does (its cylinder is never shorter than its radius); ``robust_aggr`` is
``median=True``; py4dgeo has no minimum point count, so ``min_points=1``.

Where the results differ from py4dgeo's (docs/validation.md lists py4dgeo's defects):
``lodetection`` uses the exact normal quantile (1.959963984540054 at 95 %) where py4dgeo uses
1.96 (a relative difference of 1.8e-5); points exactly on a boundary of py4dgeo's stepped
cylinder are counted once here; core points whose normal cannot be fitted (fewer than 3
neighbours) are NaN here, uninitialised in py4dgeo; with ``robust_aggr`` the spread is
IQR / 1.349 (on the standard deviation's scale), where py4dgeo reports the IQR.

Arguments py4dgeo has but this front end does not implement raise
:class:`UnsupportedArgument` naming them; nothing is silently ignored.
"""
from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any, Union

import numpy as np

from ..run.in_memory import compare
from ..base.errors import CloudReadError, UsageError
from ..io.files import read_cloud
from ..engine.result import Result

__all__ = ["Epoch", "M3C2", "read_from_xyz", "read_from_las", "as_epoch", "set_num_threads",
           "get_num_threads", "UnsupportedArgument", "UNCERTAINTY_DTYPE"]

#: The dtype of ``M3C2.run()``'s uncertainties: py4dgeo's field names and types.
UNCERTAINTY_DTYPE = np.dtype([("lodetection", "<f8"), ("spread1", "<f8"), ("num_samples1", "<i8"),
                              ("spread2", "<f8"), ("num_samples2", "<i8")])

PathLike = Union[str, "os.PathLike[str]"]


class UnsupportedArgument(UsageError):
    """A py4dgeo argument this front end does not implement (named in the message)."""


def _refuse(where: str, given: Mapping[str, Any], supported: Iterable[str]) -> None:
    if given:
        names = ", ".join(sorted(given))
        raise UnsupportedArgument(
            f"{where}: unsupported py4dgeo argument(s) {names}; m3c2kit.compat.py4dgeo supports "
            f"{', '.join(supported)} (see docs/python.md for the m3c2kit equivalents)")


_THREADS = 0  # 0: all hardware threads, like py4dgeo's default


def set_num_threads(num_threads: int) -> None:
    """Threads for later runs (py4dgeo's ``set_num_threads``); 0 means all hardware threads."""
    global _THREADS
    n = int(num_threads)
    if n < 0:
        raise UsageError(f"set_num_threads: the thread count must be >= 0, got {num_threads!r}")
    _THREADS = n


def get_num_threads() -> int:
    """The thread count set by :func:`set_num_threads` (0: all hardware threads)."""
    return _THREADS


class Epoch:
    """One point cloud of a time series (py4dgeo's ``Epoch``): ``cloud`` is (N, 3) float64.

    ``normals`` (N, 3) and ``additional_dimensions`` (a numpy structured array of N rows) are
    kept as given; ``timestamp`` is kept as given (no parsing). The spatial index is built by
    each run, so :meth:`build_kdtree` and :meth:`build_octree` have nothing to do.
    """

    def __init__(self, cloud: np.ndarray, normals: np.ndarray | None = None,
                 additional_dimensions: np.ndarray | None = None, timestamp: Any = None,
                 **unsupported: Any) -> None:
        _refuse("Epoch", unsupported, ("cloud", "normals", "additional_dimensions", "timestamp"))
        arr = np.ascontiguousarray(cloud, dtype=np.float64)
        if arr.ndim != 2 or arr.shape[1] != 3:
            raise UsageError(f"Epoch: cloud must be an (N, 3) array, got shape {arr.shape}")
        self._cloud = arr
        if normals is not None:
            normals = np.ascontiguousarray(normals, dtype=np.float64)
            if normals.shape != arr.shape:
                raise UsageError(f"Epoch: normals must have the cloud's shape {arr.shape}, got {normals.shape}")
        self.normals = normals
        self.additional_dimensions = additional_dimensions
        self.timestamp = timestamp

    @property
    def cloud(self) -> np.ndarray:
        """The (N, 3) float64 coordinates."""
        return self._cloud

    def __len__(self) -> int:
        return len(self._cloud)

    def build_kdtree(self, leaf_size: int = 10) -> None:
        """Accepted for py4dgeo scripts: m3c2kit builds its own index in every run."""

    def build_octree(self) -> None:
        """Accepted for py4dgeo scripts: m3c2kit builds its own index in every run."""


def as_epoch(cloud: Epoch | np.ndarray) -> Epoch:
    """An :class:`Epoch` from an Epoch (returned as is) or an (N, 3) array."""
    return cloud if isinstance(cloud, Epoch) else Epoch(cloud)


def _one_or_tuple(epochs: list[Epoch]) -> Epoch | tuple[Epoch, ...]:
    # py4dgeo returns a bare Epoch for one file and a tuple for several.
    return epochs[0] if len(epochs) == 1 else tuple(epochs)


def read_from_xyz(*filenames: PathLike, xyz_columns: Sequence[int] = (0, 1, 2),
                  normal_columns: Sequence[int] = (), additional_dimensions: Mapping[int, str] | None = None,
                  additional_dimensions_dtypes: Mapping[str, Any] | None = None,
                  **parse_opts: Any) -> Epoch | tuple[Epoch, ...]:
    """Epochs from delimited text files (py4dgeo's ``read_from_xyz``).

    ``xyz_columns`` / ``normal_columns``: 0-based column indices; ``additional_dimensions``:
    column index -> name, read into a structured array; ``parse_opts`` go to
    :func:`numpy.genfromtxt` (e.g. ``delimiter=","``, ``skip_header=1``), as in py4dgeo.
    One file gives an Epoch, several a tuple of Epochs.
    """
    if not filenames:
        raise UsageError("read_from_xyz: give at least one file name")
    if "usecols" in parse_opts:
        raise UsageError("read_from_xyz: use xyz_columns, normal_columns or additional_dimensions, not usecols")
    if len(xyz_columns) != 3:
        raise UsageError(f"read_from_xyz: xyz_columns must name 3 columns, got {list(xyz_columns)}")
    if normal_columns and len(normal_columns) != 3:
        raise UsageError(f"read_from_xyz: normal_columns must name 3 columns, got {list(normal_columns)}")
    extra = dict(additional_dimensions or {})
    dtypes = dict(additional_dimensions_dtypes or {})
    epochs = []
    for name in filenames:
        path = Path(name)
        if not path.is_file():
            raise CloudReadError(f"{path}: no such file")

        def columns(cols, dtype=np.float64, path=path):
            try:
                out = np.genfromtxt(path, dtype=dtype, usecols=tuple(cols), **parse_opts)
            except (ValueError, IndexError) as e:
                raise CloudReadError(f"{path}: malformed text file ({e})") from None
            return out

        xyz = np.atleast_2d(columns(xyz_columns))
        if xyz.shape[1] != 3 or len(xyz) == 0:
            raise CloudReadError(f"{path}: no points read from columns {list(xyz_columns)}")
        if not np.isfinite(xyz).all():
            raise CloudReadError(f"{path}: some coordinates are missing or not numbers")
        normals = np.atleast_2d(columns(normal_columns)) if normal_columns else None
        dims = None
        if extra:
            dt = np.dtype([(label, dtypes.get(label, np.float64)) for label in extra.values()])
            dims = np.atleast_1d(columns(extra.keys(), dt))
        epochs.append(Epoch(xyz, normals=normals, additional_dimensions=dims))
    return _one_or_tuple(epochs)


def read_from_las(*filenames: PathLike, normal_columns: Sequence[str] = (),
                  additional_dimensions: Mapping[str, str] | None = None) -> Epoch | tuple[Epoch, ...]:
    """Epochs from LAS/LAZ files (py4dgeo's ``read_from_las``), read by m3c2kit's LAS reader.

    ``normal_columns``: the names of 3 LAS dimensions holding normals; ``additional_dimensions``:
    LAS dimension name -> name in the epoch's structured array.
    """
    if not filenames:
        raise UsageError("read_from_las: give at least one file name")
    if normal_columns and len(normal_columns) != 3:
        raise UsageError(f"read_from_las: normal_columns must name 3 dimensions, got {list(normal_columns)}")
    extra = dict(additional_dimensions or {})
    epochs = []
    for name in filenames:
        cloud = read_cloud(name)

        def field(dim: str, cloud=cloud) -> np.ndarray:
            if dim not in cloud.fields:
                raise CloudReadError(f"{cloud.path}: no dimension {dim!r} (it has {', '.join(cloud.fields)})")
            return np.asarray(cloud.fields[dim])

        normals = np.column_stack([field(c) for c in normal_columns]) if normal_columns else None
        dims = None
        if extra:
            dims = np.empty(len(cloud), dtype=[(label, field(dim).dtype) for dim, label in extra.items()])
            for dim, label in extra.items():
                dims[label] = field(dim)
        epochs.append(Epoch(cloud.xyz, normals=normals, additional_dimensions=dims))
    return _one_or_tuple(epochs)


_AXES = {(1.0, 0.0, 0.0): "+x", (-1.0, 0.0, 0.0): "-x", (0.0, 1.0, 0.0): "+y", (0.0, -1.0, 0.0): "-y",
         (0.0, 0.0, 1.0): "+z", (0.0, 0.0, -1.0): "-z"}

_M3C2_ARGUMENTS = ("epochs", "corepoints", "normal_radii", "cyl_radius", "cyl_radii", "max_distance",
                   "registration_error", "robust_aggr", "orientation_vector", "corepoint_normals",
                   "cloud_for_normals")


def _positive(name: str, value: Any) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise UsageError(f"M3C2: {name} must be a positive number, got {value!r}") from None
    if not v > 0 or not np.isfinite(v):
        raise UsageError(f"M3C2: {name} must be a positive number, got {value!r}")
    return v


class M3C2:
    """py4dgeo's ``M3C2`` class computed by m3c2kit (see the module docstring for the mapping).

    ``run()`` returns ``(distances, uncertainties)``: distances (N,) float64, NaN where not
    computed; uncertainties a structured array with py4dgeo's fields ``lodetection``,
    ``spread1``, ``num_samples1``, ``spread2``, ``num_samples2``. :attr:`result` then holds the
    full :class:`m3c2kit.Result` (status codes, significance, roughness, ...).
    """

    def __init__(self, epochs: Sequence[Epoch | np.ndarray] | None = None,
                 corepoints: np.ndarray | None = None, normal_radii: Sequence[float] | None = None,
                 cyl_radius: float | None = None, cyl_radii: Sequence[float] | None = None,
                 max_distance: float = 0.0, registration_error: float = 0.0, robust_aggr: bool = False,
                 orientation_vector: Sequence[float] | np.ndarray = (0.0, 0.0, 1.0),
                 corepoint_normals: np.ndarray | None = None,
                 cloud_for_normals: Epoch | np.ndarray | None = None, **unsupported: Any) -> None:
        _refuse("M3C2", unsupported, _M3C2_ARGUMENTS)
        self.epochs = epochs
        self.corepoints = corepoints
        self.normal_radii = normal_radii
        self.cyl_radius = cyl_radius
        self.cyl_radii = cyl_radii
        self.max_distance = max_distance
        self.registration_error = registration_error
        self.robust_aggr = robust_aggr
        self.orientation_vector = orientation_vector
        self.corepoint_normals = corepoint_normals
        self.cloud_for_normals = cloud_for_normals
        self.result: Result | None = None

    @property
    def name(self) -> str:
        return "M3C2"

    def _radius(self) -> float:
        radius = self.cyl_radius
        if self.cyl_radii is not None:
            radii = list(self.cyl_radii)
            if len(radii) != 1:
                raise UsageError(f"M3C2: cyl_radii must hold exactly one radius, got {radii}")
            if radius is None:
                radius = radii[0]
        if radius is None:
            raise UsageError("M3C2: give the cylinder radius, cyl_radius=r (m3c2kit's projection_scale is 2r)")
        return _positive("cyl_radius", radius)

    def _orient(self) -> str:
        v = np.asarray(self.orientation_vector, dtype=np.float64).ravel()
        norm = float(np.linalg.norm(v)) if v.shape == (3,) else 0.0
        if not norm > 0 or not np.isfinite(norm):
            raise UsageError(f"M3C2: orientation_vector must be a non-zero 3-vector, got {self.orientation_vector!r}")
        axis = _AXES.get(tuple(float(c) for c in v / norm))
        if axis is None:
            raise UnsupportedArgument(
                f"M3C2: orientation_vector {v.tolist()} is not along an axis; m3c2kit orients normals "
                f"towards +x, -x, +y, -y, +z or -z, or towards points (m3c2kit.compare(orient=...))")
        return axis

    def _normal_options(self, reference: np.ndarray, compared: np.ndarray, n_core: int) -> dict[str, Any]:
        if self.corepoint_normals is not None:
            normals = np.asarray(self.corepoint_normals, dtype=np.float64)
            if normals.ndim == 2 and normals.shape == (1, 3):
                normals = np.repeat(normals, n_core, axis=0)
            if normals.shape != (n_core, 3):
                raise UsageError(f"M3C2: corepoint_normals must be (1, 3) or ({n_core}, 3), got {normals.shape}")
            return {"normal_source": "core", "core_normals": normals}
        if not self.normal_radii:
            raise UsageError("M3C2: give normal_radii (a list of radii; m3c2kit's normal_scale is 2 x radius)")
        scales = [2.0 * _positive("normal_radii", r) for r in self.normal_radii]
        options: dict[str, Any] = {"normal_scale": scales if len(scales) > 1 else scales[0]}
        if len(scales) > 1:
            options["min_points_multiscale"] = 3  # py4dgeo takes any scale with a plane (3 points)
        source = self.cloud_for_normals
        if source is not None:
            cloud = as_epoch(source).cloud
            if cloud is compared or np.array_equal(cloud, compared):
                options["normal_source"] = "compared"
            elif not (cloud is reference or np.array_equal(cloud, reference)):
                raise UnsupportedArgument("M3C2: cloud_for_normals must be one of the two epochs (m3c2kit "
                                          "fits normals on the reference, the compared cloud or their mean)")
        return options

    def run(self) -> tuple[np.ndarray, np.ndarray]:
        """(distances, uncertainties) at the core points, in their order."""
        if self.epochs is None or len(self.epochs) != 2:
            raise UsageError("M3C2: epochs must be a pair (reference, compared)")
        reference, compared = (as_epoch(e).cloud for e in self.epochs)
        if self.corepoints is None:
            raise UsageError("M3C2: give corepoints, an (N, 3) array")
        core = np.ascontiguousarray(self.corepoints, dtype=np.float64)
        if core.ndim != 2 or core.shape[1] != 3:
            raise UsageError(f"M3C2: corepoints must be an (N, 3) array, got shape {core.shape}")
        radius = self._radius()
        depth = max(float(self.max_distance), radius)  # py4dgeo: the cylinder reaches at least r
        options = self._normal_options(reference, compared, len(core))
        orient = self._orient()  # checked always; given normals are used as they are (as py4dgeo's)
        if options.get("normal_source") != "core":
            options["orient"] = orient
        result = compare(reference, compared, core, projection_scale=2.0 * radius, max_depth=depth,
                         registration_error=float(self.registration_error), median=bool(self.robust_aggr),
                         min_points=1, lod="z", threads=_THREADS, **options)  # py4dgeo's z
        self.result = result
        return result.distance, uncertainties_of(result)

    def directions(self) -> np.ndarray:
        """The (N, 3) normals of the last run (NaN where none could be fitted)."""
        return self._result().normal

    def directions_radii(self) -> np.ndarray:
        """The normal radius (our chosen diameter / 2) per core point of the last run."""
        return self._result().normal_scale / 2.0

    def _result(self) -> Result:
        if self.result is None:
            raise UsageError("M3C2: call run() first")
        return self.result


def uncertainties_of(result: Result) -> np.ndarray:
    """py4dgeo's uncertainty array (:data:`UNCERTAINTY_DTYPE`) from an m3c2kit Result."""
    out = np.empty(len(result), dtype=UNCERTAINTY_DTYPE)
    out["lodetection"] = result.lod
    out["spread1"], out["spread2"] = result.sigma1, result.sigma2
    out["num_samples1"], out["num_samples2"] = result.n1, result.n2
    return out
