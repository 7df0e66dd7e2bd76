"""The optional dependencies, each behind its extra (pyproject.toml): the one place that imports them.

The core install (numpy, laspy[lazrs]) reads and writes LAS/LAZ, PLY, ASCII and .npy and runs
every computation. A feature whose library is missing fails when it is used, with a message
naming the extra that brings it, never at ``import m3c2kit``:

============  ====================  ==========================================
extra         library               needed for
============  ====================  ==========================================
``crs``       pyproj                telling two different CRS texts apart (the
                                    same text always passes), CRS names and
                                    units, ``--crs``
``progress``  tqdm                  progress bars (without it: one line per
                                    phase on stderr)
``raster``    rasterio              ``--grid`` GeoTIFFs
``e57``       pye57                 reading .e57 files
``dask``      dask[distributed]     ``--dask-scheduler``
``report``    matplotlib, plotly    ``--report``, ``--report-png``, analysis plots
``classify``  scikit-learn          ``m3c2 classify train``
``series``    xarray, zarr, dask    ``m3c2 series``
``all``       all of the above
============  ====================  ==========================================
"""
from __future__ import annotations

import importlib
from types import ModuleType

from .errors import M3C2Error

__all__ = ["MissingExtraError", "require", "lazy_module"]


class MissingExtraError(M3C2Error, ImportError):
    """An optional feature was used without its extra installed (also an ImportError)."""

    def __init__(self, message: str, module: str, extra: str):
        super().__init__(message)
        self.name = module
        self.extra = extra


def require(module: str, extra: str, purpose: str) -> ModuleType:
    """Imports ``module`` (``"rasterio.transform"``), or raises MissingExtraError:
    ``"{purpose} needs the {extra} extra: pip install 'm3c2kit[{extra}]'"``."""
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as err:
        missing = (err.name or module).split(".")[0]
        if missing != module.split(".")[0]:
            raise  # the library is there but one of its own dependencies is missing: show that
        raise MissingExtraError(f"{purpose} needs the {extra} extra: pip install 'm3c2kit[{extra}]' "
                                f"(no module named {missing!r})", missing, extra) from None
    except ImportError as err:
        # Installed but broken (a binary built for another numpy: "numpy.core.multiarray failed to
        # import"): its real cause, not "no module named" and advice to install what is there (issue 44).
        raise M3C2Error(f"{purpose} needs {module.split('.')[0]}, which is installed but does not import: "
                        f"{' '.join(str(err).split())} (reinstall it for this numpy: pip install --force-reinstall "
                        f"'m3c2kit[{extra}]')") from None


class _LazyModule:
    """A module imported on first use of one of its attributes (through require())."""

    def __init__(self, module: str, extra: str, purpose: str):
        self._args = (module, extra, purpose)

    def __getattr__(self, name: str):
        return getattr(require(*self._args), name)


def lazy_module(module: str, extra: str, purpose: str):
    """A stand-in for ``import module`` at the top of a file: the import (and its error) happen at
    the first attribute access, so importing the file needs no optional library."""
    return _LazyModule(module, extra, purpose)
