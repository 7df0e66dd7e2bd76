"""No copies between reading a LAZ file and the engine (issue 19): the reader computes the
float64 coordinates once, straight into the C-contiguous (n, 3) array the engine takes, with
laspy's own bits, and the API hands that very array on."""
from __future__ import annotations

import tracemalloc

import laspy
import numpy as np

import m3c2kit
from m3c2kit.run.checks import as_points


def _laz(path, n=200_000):
    rng = np.random.default_rng(7)
    header = laspy.LasHeader(version="1.4", point_format=6)
    header.scales, header.offsets = np.array([0.001, 0.002, 0.0005]), np.array([1000.0, -20.0, 3.0])
    las = laspy.LasData(header)
    las.x, las.y, las.z = rng.uniform(1000, 1100, n), rng.uniform(-20, 80, n), rng.uniform(3, 13, n)
    las.write(str(path))
    return path


def test_coordinates_are_laspys_bits_in_one_engine_ready_array(tmp_path):
    path = _laz(tmp_path / "a.laz")
    cloud = m3c2kit.read(path)
    las = laspy.read(str(path))
    expected = np.column_stack([las.x, las.y, las.z])
    assert np.array_equal(cloud.xyz.view(np.uint64), expected.view(np.uint64))
    assert cloud.xyz.dtype == np.float64 and cloud.xyz.flags.c_contiguous
    handed = as_points("reference", cloud)
    assert handed is cloud.xyz or np.shares_memory(handed, cloud.xyz)


def test_reading_peaks_within_a_third_of_a_coordinate_copy(tmp_path):
    path = _laz(tmp_path / "b.laz")
    m3c2kit.read(path)  # imports and first-use set-up outside the measurement
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        cloud = m3c2kit.io.read_cloud(path)
        retained, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    # What is kept (coordinates, fields, laspy's point records the fields view) plus at most one
    # coordinate column (8 bytes a point) of transient memory: a stacked, transposed or
    # converted copy of the coordinates (24 bytes a point) would exceed it.
    assert peak - retained <= cloud.xyz.nbytes / 3, (peak - retained) / len(cloud)
    assert retained >= cloud.xyz.nbytes  # the measurement sees numpy's allocations at all
