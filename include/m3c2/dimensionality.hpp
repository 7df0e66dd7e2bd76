#pragma once
// Multi-scale dimensionality features of Brodu & Lague (2012, ISPRS J. 68, "CANUPO"), the
// vegetation classifier the M3C2 paper runs before comparing (Lague et al. 2013, section 4.3).
// At each core point and each scale (a sphere DIAMETER, as everywhere in m3c2), the eigenvalues
// of the covariance of the neighbours, normalised to sum 1, and their barycentric coordinates in
// the triangle of the 1D (line), 2D (plane) and 3D (volume) configurations (docs/algorithm.md,
// "Multi-scale dimensionality").

#include <m3c2/points_view.hpp>
#include <m3c2/result.hpp>
#include <m3c2/run_options.hpp>

#include <cstdint>
#include <vector>

namespace m3c2 {

/// Per core point i and scale k (k in the order of the diameters given), row-major.
struct DimensionalityResult {
  std::size_t scales = 0;
  /// [i][k][j], 3 per scale: p_j = lambda_j / (lambda_1 + lambda_2 + lambda_3), descending
  /// (p_1 >= p_2 >= p_3 >= 0, sum 1). NaN where the core point has no features (status).
  std::vector<double> proportions;
  /// [i][k][j], 3 per scale: (a, b, c) = (p_1 - p_2, 2 (p_2 - p_3), 3 p_3), the weights of the
  /// 1D, 2D and 3D vertices (1,0,0), (1/2,1/2,0), (1/3,1/3,1/3) that give (p_1, p_2, p_3).
  std::vector<double> barycentric;
  /// [i][k]: neighbours within the sphere (squared distance <= (D/2)^2), the core point included
  /// when it is a point of the cloud.
  std::vector<std::uint32_t> count;
  /// kOk; kTooFewNormalPoints: fewer than min_points at the largest scale; kDegenerateNormal:
  /// enough points but all coincident (no variance) at every such scale.
  std::vector<PointStatus> status;

  std::size_t size() const { return status.size(); }
};

/// Features of `cloud` at `core_points` for each of `diameters` (positive, distinct). A scale
/// with fewer than `min_points` (>= 3) neighbours, or with coincident ones, takes the values of
/// the next larger scale, as CANUPO does (Brodu & Lague 2012; qCANUPO's descriptor): its count
/// says so. Bit-identical for any thread count and any tile holding each neighbourhood whole
/// (sums over the neighbours in the octree's key order, src/features/dimensionality.cpp: a function of the
/// neighbours and their relative input order). At most 255 scales. Throws InvalidArgument on bad
/// inputs.
DimensionalityResult dimensionality(PointsView cloud, PointsView core_points, const std::vector<double>& diameters,
                                    std::uint32_t min_points = 3, const RunOptions& run = {});

}  // namespace m3c2
