#pragma once
// The M3C2 engine (Lague, Brodu & Leroux 2013): pure computation on float64 arrays.
// Every function is deterministic: the same inputs give the same bits for any thread count.
// See docs/algorithm.md for each equation, its paper reference and the choices made.

#include <m3c2/baselines.hpp>
#include <m3c2/dimensionality.hpp>
#include <m3c2/errors.hpp>
#include <m3c2/params.hpp>
#include <m3c2/points_view.hpp>
#include <m3c2/result.hpp>
#include <m3c2/run_options.hpp>
#include <m3c2/uncertainty.hpp>

#include <cstdint>
#include <optional>
#include <vector>

namespace m3c2 {

/// M3C2 distance, LOD and significance at each core point (sections 3.1-3.3, Appendix B).
/// `core_normals` (3 per core point) is read only with NormalSource::kCorePoints.
/// `uncertainty` holds the per-point inputs of params.uncertainty (PM, EP; uncertainty.hpp).
/// Throws InvalidArgument on bad parameters or inputs, Cancelled if the progress callback says so.
Result compute(PointsView reference, PointsView compared, PointsView core_points, const Params& params,
               const RunOptions& run = {}, const std::vector<double>& core_normals = {},
               const UncertaintyInputs& uncertainty = {});

/// The largest |coordinate| of a cloud compute() accepts with these parameters: its spatial index
/// keys 2^40 cells of a grid that follows the smallest diameter (D / 16, or d / 16 without
/// normal diameters; docs/algorithm.md). Beyond it compute() throws InvalidArgument.
double max_abs_coordinate(const Params& params);

/// Largest distance from a core point to a point that can change its result: the normal sphere
/// (largest D / 2) or the cylinder (radius d / 2, half-length max_depth, any direction).
double neighbourhood_reach(const Params& params);

/// The halo a tile of core points needs (neighbourhood_reach plus a hair of margin): a tile
/// computed from the points within this distance of its core points' bounding box gives the same
/// bits as the whole clouds (docs/scaling.md).
double tile_halo(const Params& params);

/// Most cells along an axis of the integer grids of subsample_min_spacing and grid_core_points
/// (extent / cell): beyond it their cell indices would stop being exact, and they throw.
inline constexpr double kMaxCellsPerAxis = 1099511627776.0;  // 2^40

/// What compute() allocates beyond its inputs, for a caller's memory check: an upper estimate
/// (docs/performance.md, "Memory, byte by byte"; tests/python/test_memory_estimate.py measures it).
struct IndexMemory {
  /// Each cloud: its uint32 original index (4); its nodes, counted at 3/8 of a node per point
  /// (64 B each: 24; surfaces take up to 0.22 a point, volumes up to 0.35, at about a point per
  /// finest cell, and the array is reserved for 0.5 so that it never holds two copies below that);
  /// and the build's sort keys (16: 128-bit for a cloud of more than about 2^20 cells a side),
  /// which are freed before the nodes are bounded but, below glibc's largest mmap threshold
  /// (32 MiB of keys), stay in the process's heap.
  double bytes_per_point = 4 + 24 + 16;
  /// Each cloud copied, not ordered in place: its float64 coordinates in key order.
  double copy_bytes_per_point = 24;
  /// Each cloud whose normals are computed: its node moments (80 B per node, 3/8 of a node per point).
  double moments_bytes_per_point = 30;
  double overhead = 1.05;             ///< the allocator's slack
  double bytes_per_core_point = 120;  ///< the Result's vectors (98 B) and the per-thread scratch
};
IndexMemory index_memory();

/// Bytes compute() allocates beyond its inputs for clouds of these sizes (IndexMemory): moments
/// on the clouds whose normals `params` computes, and no copies where the clouds are ordered in
/// place (`order_clouds_in_place` and the parameters allow it).
double memory_estimate(std::size_t n_reference, std::size_t n_compared, std::size_t n_core, const Params& params,
                       bool order_clouds_in_place = false);

/// Normals of `cloud` at `core_points` with params.normal_diameters (one scale or multi-scale),
/// oriented by params.orientation, with roughness sigma(D) (sections 3.1.2, 3.2, 6.3).
/// Reads normal_diameters, scale_selection, min_points_normal, min_points_multiscale,
/// normal_subsample_spacing, orientation and variance.
NormalsResult compute_normals(PointsView cloud, PointsView core_points, const Params& params,
                              const RunOptions& run = {});

/// Roughness sigma(D) at each core point for each diameter (section 5.1, Fig. 6a): row-major
/// [core point][scale], NaN where fewer than `min_points` neighbours.
std::vector<double> roughness_by_scale(PointsView cloud, PointsView core_points, const std::vector<double>& diameters,
                                       Variance variance, std::uint32_t min_points, const RunOptions& run = {});

/// Indices of a subset of `points` in which no two points are closer than `min_spacing`,
/// chosen greedily in input order (the first point of a cluster is kept). Serial and
/// deterministic; the result is sorted.
std::vector<std::uint64_t> subsample_min_spacing(PointsView points, double min_spacing);

/// For each row of `queries`, the index of the first row of `points` equal to it (as numbers:
/// -0.0 equals 0.0, NaN equals nothing), in input order; nullopt when some query equals no row.
/// Queries equal to the points row for row (the core points are the cloud) get the identity.
/// How the command line finds the reference points that the core points are, to carry their
/// attributes (intensity, classification, ...) into the output. Serial; O(points + queries).
std::optional<std::vector<std::uint64_t>> match_rows(PointsView points, PointsView queries);

/// Regular grid of core points over the XY extent of `points` (2D use, section 3.1.1 and 6.1.2).
struct Grid {
  double x0 = 0, y0 = 0, cell = 0;  ///< centre of cell (row r, col c) is (x0 + (c + .5) cell, y0 + (r + .5) cell)
  std::uint64_t rows = 0, cols = 0;
  std::vector<double> core_points;      ///< row-major xyz: one per non-empty cell, z = median z there
  std::vector<std::uint64_t> row, col;  ///< cell of each core point
};
Grid grid_core_points(PointsView points, double cell);

}  // namespace m3c2
