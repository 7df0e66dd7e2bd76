"""py4dgeo's Epoch and its readers (py4dgeo 1.2.0's py4dgeo/epoch.py) on m3c2kit's readers."""
from __future__ import annotations

import datetime
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Union

import numpy as np

from ...base.errors import CloudReadError, UsageError
from ...io.files import read_cloud
from .errors import Py4DGeoError, refuse, translated
from .transformation import Transformation

__all__ = ["Epoch", "as_epoch", "read_from_xyz", "read_from_las", "normalize_timestamp"]

PathLike = Union[str, "os.PathLike[str]"]


@translated
def normalize_timestamp(timestamp: Any) -> datetime.datetime | None:
    """py4dgeo's rule: None or a datetime as it is; a date at midnight; a LAS header's (year, day
    of year); a string in ISO 8601 ('2024-05-01', '2024-05-01T12:30:00', '2024-05-01 12:30').
    py4dgeo reads any human-readable text with the dateparser library ('yesterday', '1 May
    2024'); m3c2kit has no such dependency and names the forms it reads (docs/python.md)."""
    if timestamp is None or isinstance(timestamp, datetime.datetime):
        return timestamp
    if isinstance(timestamp, datetime.date):
        return datetime.datetime(timestamp.year, timestamp.month, timestamp.day)
    if isinstance(timestamp, np.datetime64):
        return normalize_timestamp(str(np.datetime_as_string(timestamp, unit="us")))
    if isinstance(timestamp, (tuple, list)) and len(timestamp) == 2:
        year, day = timestamp
        return datetime.datetime(int(year), 1, 1) + datetime.timedelta(int(day) - 1)
    if isinstance(timestamp, str):
        try:
            return datetime.datetime.fromisoformat(timestamp.strip())
        except ValueError:
            pass
    raise UsageError(f"The timestamp {timestamp!r} was not understood: give a datetime, a date, (year, day of year) "
                     f"or ISO 8601 text such as '2024-05-01T12:30:00' (py4dgeo also reads free text through "
                     f"dateparser; m3c2kit does not)")


class Epoch:
    """One point cloud of a time series (py4dgeo's ``Epoch``): ``cloud`` is (N, 3) float64.

    ``normals`` (N, 3) and ``additional_dimensions`` (a numpy structured array of N rows) are
    kept as given; ``timestamp`` is normalised as py4dgeo's (:func:`normalize_timestamp`), and
    ``scanpos_info`` (M3C2-EP's scan positions) as py4dgeo's: a list of one dict per scan
    position, ``scanpos_id`` (one id per point, counted from 1) in ``additional_dimensions``. The
    spatial index is built by each run, so :meth:`build_kdtree` and :meth:`build_octree` have
    nothing to do.
    """

    @translated
    def __init__(self, cloud: np.ndarray, normals: np.ndarray | None = None,
                 additional_dimensions: np.ndarray | None = None, timestamp: Any = None,
                 scanpos_info: dict | None = None, **unsupported: Any) -> None:
        refuse("Epoch", unsupported, ("cloud", "normals", "additional_dimensions", "timestamp", "scanpos_info"))
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
        self.scanpos_info = scanpos_info
        self._transformations: list = []

    @property
    def normals(self) -> np.ndarray | None:
        """The (N, 3) normals, or None."""
        return self._normals

    @normals.setter
    def normals(self, value: np.ndarray | None) -> None:
        self._normals = value
        self._normals_radius = None  # normals from elsewhere: their neighbourhood is not known

    @property
    def normals_radius(self) -> float | None:
        """m3c2kit's addition: the radius :meth:`calculate_normals` fitted :attr:`normals` at, None
        for normals given otherwise (the registration functions fit their planes at 2 x radius)."""
        return self._normals_radius

    def _with_normals_of(self, other: "Epoch") -> "Epoch":
        self._normals_radius = other._normals_radius  # a subset or copy keeps each point's normal
        return self

    @property
    def cloud(self) -> np.ndarray:
        """The (N, 3) float64 coordinates."""
        return self._cloud

    @cloud.setter
    def cloud(self, value: Any) -> None:
        raise Py4DGeoError("The Epoch point cloud cannot be changed after initialization. Please construct a new "
                           "Epoch, e.g. by slicing an existing one.")

    def __setattr__(self, name: str, value: Any) -> None:
        # py4dgeo's search trees are not provided (m3c2kit's engine builds its index in each run), and
        # py4dgeo refuses their assignment: so does this Epoch, rather than keep an unused attribute.
        if name in ("kdtree", "octree"):
            raise Py4DGeoError(f"The {'KDTree' if name == 'kdtree' else 'Octree'} of an Epoch cannot be changed.")
        super().__setattr__(name, value)

    @property
    def timestamp(self) -> datetime.datetime | None:
        return self._timestamp

    @timestamp.setter
    def timestamp(self, value: Any) -> None:
        self._timestamp = normalize_timestamp(value)

    @property
    def scanpos_info(self) -> list | None:
        """M3C2-EP's scan positions: one dict per scan position (``origin`` [x, y, z],
        ``sigma_range``, ``sigma_scan``, ``sigma_yaw``), scan position k at index k - 1."""
        return self._scanpos_info

    @scanpos_info.setter
    @translated
    def scanpos_info(self, value: list | dict | None) -> None:
        # py4dgeo's rule: a list as it is, a dict {"1": {...}, "2": {...}} as the list of its ids
        # 1..K in order (py4dgeo drops any other value to None; refused here).
        if value is None or isinstance(value, list):
            self._scanpos_info = value
        elif isinstance(value, dict):
            keyed = {str(k): v for k, v in value.items()}
            ids = [str(k) for k in range(1, len(keyed) + 1)]
            if sorted(keyed) != sorted(ids):
                raise UsageError(f"Epoch: scanpos_info's keys must be the scan position ids 1..{len(keyed)}, got "
                                 f"{', '.join(sorted(keyed))}")
            self._scanpos_info = [keyed[k] for k in ids]
        else:
            raise UsageError(f"Epoch: scanpos_info must be a list or a dict of scan positions, got "
                             f"{type(value).__name__}")

    @property
    @translated
    def scanpos_id(self) -> np.ndarray:
        """Each point's scan position id (int32, counted from 1): ``additional_dimensions["scanpos_id"]``."""
        dims = self.additional_dimensions
        if dims is None or dims.dtype.names is None or "scanpos_id" not in dims.dtype.names:
            raise UsageError("Epoch: no scanpos_id: set epoch.scanpos_id, or read it, e.g. read_from_las(..., "
                             "additional_dimensions={'point_source_id': 'scanpos_id'})")
        return np.asarray(dims["scanpos_id"]).reshape(len(self._cloud)).astype(np.int32)

    @scanpos_id.setter
    @translated
    def scanpos_id(self, value) -> None:
        ids = np.asarray(value).reshape(-1)
        if len(ids) != len(self._cloud):
            raise UsageError(f"Epoch: scanpos_id must hold one id per point ({len(self._cloud)}), got {len(ids)}")
        ids = ids.astype(np.int32)
        dims = self.additional_dimensions
        if dims is not None and dims.dtype.names is None:
            raise UsageError("Epoch: scanpos_id joins additional_dimensions, which must then be a structured array")
        kept = [] if dims is None else [n for n in dims.dtype.names if n != "scanpos_id"]
        out = np.empty(len(ids), dtype=[(n, dims.dtype[n]) for n in kept] + [("scanpos_id", "<i4")])
        for name in kept:
            out[name] = np.asarray(dims[name]).reshape(len(ids))
        out["scanpos_id"] = ids
        self.additional_dimensions = out

    @property
    def metadata(self) -> dict:
        """py4dgeo's metadata: what ``Epoch(cloud, **other.metadata)`` takes, JSON-serialisable."""
        return {"timestamp": None if self.timestamp is None else str(self.timestamp),
                "scanpos_info": self.scanpos_info}

    def __len__(self) -> int:
        return len(self._cloud)

    def __getitem__(self, index) -> "Epoch":
        """A copy of the selected points (e.g. ``epoch[::10]`` to subsample), with the metadata."""
        pick = lambda a: None if a is None else a[index]  # noqa: E731
        return Epoch(self._cloud[index], normals=pick(self.normals), additional_dimensions=pick(
            self.additional_dimensions), **self.metadata)._with_normals_of(self)

    def copy(self) -> "Epoch":
        copied = lambda a: None if a is None else a.copy()  # noqa: E731
        return Epoch(self._cloud.copy(), normals=copied(self.normals),
                     additional_dimensions=copied(self.additional_dimensions), timestamp=self.timestamp,
                     scanpos_info=copied(self.scanpos_info))._with_normals_of(self)

    @translated
    def transform(self, transformation=None, affine_transformation=None, rotation=None, translation=None,
                  reduction_point=None) -> None:
        """py4dgeo's ``Epoch.transform``, in place: x' = A (x - r) + t + r with the affine A | t (a
        4x4 or 3x4 matrix, or rotation and translation; or a :class:`Transformation`, as the
        registration functions return, whose reduction point is then r), r the reduction point
        (0 by default); normals are rotated. Recorded in :attr:`transformation`."""
        if transformation is not None:
            if not (hasattr(transformation, "affine_transformation") and hasattr(transformation, "reduction_point")):
                raise UsageError(f"Epoch.transform: transformation must be a Transformation (affine_transformation "
                                 f"and reduction_point), got {type(transformation).__name__}")
            affine_transformation = transformation.affine_transformation
            reduction_point = transformation.reduction_point
        if affine_transformation is None:
            if rotation is None or translation is None:
                raise UsageError("Epoch.transform: give transformation, affine_transformation, or rotation and "
                                 "translation")
            trafo = np.identity(4)
            trafo[:3, :3], trafo[:3, 3] = rotation, np.ravel(translation)
        else:
            given = np.asarray(affine_transformation, dtype=np.float64)
            if given.shape not in ((3, 4), (4, 4)) or not np.isfinite(given).all():
                raise UsageError(f"Epoch.transform: the affine transformation must be a finite 3x4 or 4x4 matrix, "
                                 f"got shape {given.shape}")
            trafo = np.identity(4)
            trafo[:3] = given[:3]
        r = np.zeros(3) if reduction_point is None else np.asarray(reduction_point, dtype=np.float64).ravel()
        if r.shape != (3,) or not np.isfinite(r).all():
            raise UsageError(f"Epoch.transform: the reduction point must be 3 finite numbers, got {reduction_point!r}")
        linear, shift = trafo[:3, :3], trafo[:3, 3]
        self._cloud = np.ascontiguousarray((self._cloud - r) @ linear.T + (shift + r))
        if self._normals is not None:  # the same normals turned: their radius still holds
            self._normals = np.ascontiguousarray(self._normals @ linear.T)
        self._transformations.append(Transformation(affine_transformation=trafo, reduction_point=r))

    @property
    def transformation(self) -> list:
        """The transformations applied by :meth:`transform`, as py4dgeo's: one
        :class:`Transformation` (4x4 matrix, reduction point) each."""
        return list(self._transformations)

    @translated
    def calculate_normals(self, radius: float = 1.0, orientation_vector=(0.0, 0.0, 1.0)) -> np.ndarray:
        """py4dgeo's ``Epoch.calculate_normals``: every point's normal from its neighbours within
        `radius` (m3c2kit's normal at D = 2 radius), towards `orientation_vector`; kept as
        :attr:`normals` (NaN where no plane could be fitted) and returned."""
        from .normals import direction, oriented_normals
        if not (isinstance(radius, (int, float)) and np.isfinite(radius) and radius > 0):
            raise UsageError(f"Epoch.calculate_normals: radius must be a positive number, got {radius!r}")
        self.normals, _ = oriented_normals(self._cloud, self._cloud, [radius],
                                           direction(orientation_vector, "Epoch.calculate_normals"))
        self._normals_radius = float(radius)
        return self.normals

    def build_kdtree(self, leaf_size: int = 10, force_rebuild: bool = False) -> None:
        """Accepted for py4dgeo scripts: m3c2kit builds its own index in every run."""

    def build_octree(self) -> None:
        """Accepted for py4dgeo scripts: m3c2kit builds its own index in every run."""


def as_epoch(cloud: Epoch | np.ndarray) -> Epoch:
    """An :class:`Epoch` from an Epoch (returned as is) or an (N, 3) array."""
    return cloud if isinstance(cloud, Epoch) else Epoch(cloud)


def _one_or_tuple(epochs: list[Epoch]) -> Epoch | tuple[Epoch, ...]:
    # py4dgeo returns a bare Epoch for one file and a tuple for several.
    return epochs[0] if len(epochs) == 1 else tuple(epochs)


@translated
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


@translated
def read_from_las(*filenames: PathLike, normal_columns: Sequence[str] = (),
                  additional_dimensions: Mapping[str, str] | None = None) -> Epoch | tuple[Epoch, ...]:
    """Epochs from LAS/LAZ files (py4dgeo's ``read_from_las``), read by m3c2kit's LAS reader;
    each epoch's timestamp is its header's creation date, as py4dgeo's.

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
        epochs.append(Epoch(cloud.xyz, normals=normals, additional_dimensions=dims,
                            timestamp=cloud.meta.get("creation_date")))
    return _one_or_tuple(epochs)
