"""m3c2: M3C2 point-cloud change detection (Lague, Brodu & Leroux 2013), fast and exact.

    >>> import m3c2kit
    >>> ref, cmp = m3c2kit.read("2015.laz"), m3c2kit.read("2023.laz")
    >>> r = m3c2kit.compare(ref, cmp, normal_scale=2.0, projection_scale=1.0, max_depth=5.0)
    >>> m3c2kit.write("change.laz", r, like=ref)

D (normal_scale) and d (projection_scale) are diameters; max_depth is a half-length.
"""
from .base.errors import Cancelled, M3C2Error, M3C2Warning, UsageError

#: The public names and the module each comes from, imported on first use (PEP 562): `import
#: m3c2kit` and the command line import only what a run uses (issue 45: the CANUPO classifier's
#: modules were imported by every compare, through api, and `m3c2 --version` took 0.29 s).
_LAZY = {"compare": ("api", "compare"), "normals": ("run.in_memory", "normals"),
         "subsample": ("run.in_memory", "subsample"), "register": ("analysis.registration", "register"),
         "pbm3c2": ("analysis.pbm3c2", "pbm3c2"),
         "read": ("io", "read_cloud"), "write": ("output.writing", "write"),
         "info": ("io", "info"), "Cloud": ("io", "Cloud"), "Result": ("engine.result", "Result"),
         "COLUMNS": ("engine.result", "COLUMNS"), "STATUS_NAMES": ("engine.result", "STATUS_NAMES")}

__all__ = ["compare", "normals", "subsample", "register", "pbm3c2", "read", "write", "info", "Cloud", "Result", "COLUMNS",
           "STATUS_NAMES", "M3C2Error", "UsageError", "Cancelled", "M3C2Warning"]
__version__ = "0.1.0"


#: The subpackages, also reached as attributes (`m3c2kit.io.write_cloud_table` after `import
#: m3c2kit`, as when this file imported them).
_SUBPACKAGES = ("analysis", "api", "base", "classify", "cli", "compat", "engine", "io", "output", "run", "series",
                "settings")


def __getattr__(name: str):
    from importlib import import_module
    if name in _SUBPACKAGES:
        return import_module(f".{name}", __name__)  # the import sets the attribute
    if name not in _LAZY:
        raise AttributeError(f"module 'm3c2kit' has no attribute {name!r}")
    module, attribute = _LAZY[name]
    value = getattr(import_module(f".{module}", __name__), attribute)
    globals()[name] = value  # once: later uses are plain attribute reads
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY) | set(_SUBPACKAGES))
