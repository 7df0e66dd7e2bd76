"""laspy imported for a process that reads and writes local files only: the `m3c2` command.

Importing laspy imports requests (laspy.copc, for COPC files over HTTP) and pyproj
(laspy.vlrs.geotiff binds the name and never uses it; laspy's CRS parsing imports pyproj where it
needs it): about 0.09 s of laspy's 0.12 s import, paid by every LAS/LAZ run of the command line
before its first point is read (issue 19, whole process). The command line opens paths, never
URLs, and m3c2kit imports pyproj itself where a file has a CRS (m3c2kit.io.crs), so its process
imports laspy with those two modules hidden: laspy takes them as not installed, and they stay
importable for everything else. Only the command line's own process does this (m3c2kit.cli.main.main
without arguments): in a user's process laspy keeps COPC over HTTP.
"""
from __future__ import annotations

import sys
from pathlib import Path

from . import las
from .registry import format_for

__all__ = ["UNUSED_BY_LOCAL_FILES", "names_las_file", "import_laspy_for_local_files"]

#: Imported by laspy's own import, used by no local read or write.
UNUSED_BY_LOCAL_FILES = ("requests", "pyproj")


def names_las_file(argv) -> bool:
    """Whether a command line's arguments name a LAS/LAZ/COPC file (by the extensions the
    registry gives the LAS reader)."""
    return any(getattr(format_for(Path(str(a))), "read", None) is las.read for a in argv)


def import_laspy_for_local_files() -> None:
    """Imports laspy now with :data:`UNUSED_BY_LOCAL_FILES` hidden from its import; nothing when
    laspy is already imported. Should laspy need them after all (a later laspy), it is imported
    as usual at its first use instead."""
    if "laspy" in sys.modules:
        return
    hidden = [name for name in UNUSED_BY_LOCAL_FILES if name not in sys.modules]
    for name in hidden:
        sys.modules[name] = None  # `import name` now raises ModuleNotFoundError
    try:
        import laspy  # noqa: F401
    except ImportError:
        # Missing (the readers say so where a run needs it), or needing a hidden module: its
        # partly imported modules are dropped so that the next import starts afresh.
        for name in [m for m in sys.modules if m == "laspy" or m.startswith("laspy.")]:
            del sys.modules[name]
    finally:
        for name in hidden:
            if name in sys.modules and sys.modules[name] is None:
                del sys.modules[name]
