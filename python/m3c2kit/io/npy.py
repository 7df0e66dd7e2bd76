"""NumPy .npy point arrays: an (N, 3) numeric array, or a 1-D structured array with numeric
fields x, y, z (any case; the other numeric 1-D fields are kept). Pickled objects are refused."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..base.errors import CloudReadError
from .cloud import Cloud
from .guard import read_errors

__all__ = ["read"]

_MAGIC = b"\x93NUMPY"


def read(path: Path) -> Cloud:
    """Reads a .npy file (see the module docstring); values are converted to float64."""
    with open(path, "rb") as f:
        if f.read(len(_MAGIC)) != _MAGIC:
            raise CloudReadError(f"{path}: not a NumPy .npy file (bad magic bytes)")
    with read_errors(path):
        array = np.load(path, allow_pickle=False)
    if array.dtype.names is None:
        if array.ndim != 2 or array.shape[1] != 3 or array.dtype.kind not in "iuf":
            raise CloudReadError(f"{path}: expected an (N, 3) numeric array, got shape {array.shape} "
                                 f"of {array.dtype}")
        return Cloud(array.astype(np.float64), {}, path=Path(path), format="NPY")
    if array.ndim != 1:
        raise CloudReadError(f"{path}: expected a 1-D structured array, got shape {array.shape}")
    by_lower = {name.lower(): name for name in array.dtype.names}
    missing = [a for a in "xyz" if a not in by_lower]
    if missing:
        raise CloudReadError(f"{path}: structured array has no {', '.join(missing)} field "
                             f"(fields: {', '.join(array.dtype.names)})")
    xyz = np.column_stack([array[by_lower[a]] for a in "xyz"])
    if xyz.dtype.kind not in "iuf":
        raise CloudReadError(f"{path}: x, y, z fields are not numeric ({xyz.dtype})")
    coords = {by_lower[a] for a in "xyz"}
    fields = {name: np.ascontiguousarray(array[name]) for name in array.dtype.names
              if name not in coords and array.dtype[name].kind in "biuf" and array.dtype[name].shape == ()}
    return Cloud(xyz.astype(np.float64), fields, path=Path(path), format="NPY")
