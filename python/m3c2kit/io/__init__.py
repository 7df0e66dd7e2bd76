"""Point-cloud file input and output.

    >>> from m3c2kit.io import read_cloud, write_cloud_table
    >>> cloud = read_cloud("epoch1.laz")          # Cloud: xyz (N, 3) float64 + fields + CRS
    >>> write_cloud_table("out.laz", cloud.xyz, {"distance": d}, like=cloud)

Formats by extension: LAS/LAZ/COPC (laspy), E57 (pye57), PLY, delimited text
(.xyz .txt .csv .asc .pts .neu) and .npy. Every writer is atomic (:func:`atomic_output`).
Errors are :class:`m3c2kit.base.errors.CloudReadError` / :class:`~m3c2kit.base.errors.CloudWriteError`
with messages ``"{path}: {problem}"``.
"""
from .atomic import atomic_output
from .cloud import Cloud
from .files import info, read_cloud, write_cloud_table
from .registry import SUPPORTED_READ, SUPPORTED_WRITE

__all__ = ["Cloud", "read_cloud", "write_cloud_table", "info", "atomic_output", "SUPPORTED_READ",
           "SUPPORTED_WRITE"]
