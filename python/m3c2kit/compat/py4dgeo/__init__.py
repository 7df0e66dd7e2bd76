"""py4dgeo's interface on m3c2kit's engine: a py4dgeo script runs by changing its import.

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

Registration (``iterative_closest_point``, ``point_to_plane_icp``, ``icp_with_stable_areas``,
registration.py) runs m3c2kit's point-to-plane ICP and returns a :class:`Transformation` that
``epoch.transform`` applies, as py4dgeo's; ``M3C2EP`` (m3c2ep.py) is m3c2kit's M3C2-EP set to
py4dgeo's model. Their differences from py4dgeo are in their modules' docstrings.

Time series (``SpatiotemporalAnalysis``, ``RegionGrowingAlgorithm``, ``temporal_averaging``,
segmentation.py) run on m3c2kit's series store: ``NAME.zip`` is the analysis folder
``NAME.m3c2/`` holding the store (analysis_files.py), the epochs are compared, smoothed and
segmented by ``m3c2 series``'s steps, 4D-OBC in its ``py4dgeo`` mode.

Errors are py4dgeo's: every one a :class:`Py4DGeoError` and the builtin py4dgeo's users catch
(errors.py). Arguments py4dgeo has but this front end does not implement raise
:class:`UnsupportedArgument` naming them; py4dgeo's names not provided here raise an
AttributeError naming m3c2kit's equivalent (:data:`NOT_PROVIDED`); nothing is silently ignored.
"""
from __future__ import annotations

from .epoch import Epoch, as_epoch, normalize_timestamp, read_from_las, read_from_xyz
from .errors import Py4DGeoError, UnsupportedArgument
from .m3c2 import UNCERTAINTY_DTYPE, CloudCompareM3C2, M3C2, uncertainties_of, write_m3c2_results_to_las
from .m3c2ep import COVARIANCE_DTYPE, M3C2EP
from .pbm3c2 import PBM3C2
from .registration import Transformation, icp_with_stable_areas, iterative_closest_point, point_to_plane_icp
from .segmentation import RegionGrowingAlgorithm, SpatiotemporalAnalysis, temporal_averaging
from .util import get_num_threads, regular_corepoint_grid, set_num_threads, set_py4dgeo_logfile

__all__ = ["Epoch", "M3C2", "CloudCompareM3C2", "read_from_xyz", "read_from_las", "as_epoch", "normalize_timestamp",
           "write_m3c2_results_to_las", "regular_corepoint_grid", "set_num_threads", "get_num_threads",
           "set_py4dgeo_logfile", "Py4DGeoError", "UnsupportedArgument", "UNCERTAINTY_DTYPE", "uncertainties_of",
           "M3C2EP", "COVARIANCE_DTYPE", "Transformation", "iterative_closest_point", "point_to_plane_icp",
           "icp_with_stable_areas", "PBM3C2", "SpatiotemporalAnalysis", "RegionGrowingAlgorithm", "temporal_averaging"]

#: py4dgeo 1.2.0's public names this module does not provide, and what to use instead.
NOT_PROVIDED = {
    "C2C": "m3c2 c2c REFERENCE COMPARED -o OUT",
    "SearchTree": "nothing: m3c2kit's engine builds its index in every run",
    "save_epoch": "m3c2kit.write(path, ...) to a point-cloud file",
    "load_epoch": "m3c2kit.read(path)",
    "find_file": "a plain path",
    "MemoryPolicy": "nothing: m3c2kit bounds its memory before each run",
    "set_memory_policy": "nothing: m3c2kit bounds its memory before each run",
    "Vapc": "nothing",
    "enable_trace": "nothing: m3c2kit has no tracing switch (m3c2 COMMAND --verbose prints its phases)",
    "enable_timeit": "nothing: bench/ times m3c2kit's steps",
    "initialize_openmp_defaults": "nothing: m3c2kit sets its threads per run (set_num_threads, --threads)",
    "statistical_outlier_removal": "m3c2 simplify (outlier removal, section 6.3)",
}


def __getattr__(name: str):
    if name in NOT_PROVIDED:
        raise AttributeError(f"m3c2kit.compat.py4dgeo does not provide py4dgeo's {name}; use instead: "
                             f"{NOT_PROVIDED[name]}")
    raise AttributeError(f"module 'm3c2kit.compat.py4dgeo' has no attribute {name!r}")
