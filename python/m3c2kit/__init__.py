"""m3c2: M3C2 point-cloud change detection (Lague, Brodu & Leroux 2013), fast and exact.

    >>> import m3c2kit
    >>> ref, cmp = m3c2kit.read("2015.laz"), m3c2kit.read("2023.laz")
    >>> r = m3c2kit.compare(ref, cmp, normal_scale=2.0, projection_scale=1.0, max_depth=5.0)
    >>> m3c2kit.write("change.laz", r, like=ref)

D (normal_scale) and d (projection_scale) are diameters; max_depth is a half-length.
"""
from .api import compare
from .base.errors import Cancelled, M3C2Error, M3C2Warning, UsageError
from .io import Cloud, info
from .io import read_cloud as read
from .engine.result import COLUMNS, STATUS_NAMES, Result
from .output.writing import write
from .run.in_memory import normals, subsample

__all__ = ["compare", "normals", "subsample", "read", "write", "info", "Cloud", "Result", "COLUMNS",
           "STATUS_NAMES", "M3C2Error", "UsageError", "Cancelled", "M3C2Warning"]
__version__ = "0.1.0"
