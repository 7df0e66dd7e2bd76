#pragma once
// Normals by PCA of the neighbours within a sphere of diameter D (sections 3.1.2 and 3.2).

#include "index/octree.hpp"

#include <m3c2/params.hpp>
#include <m3c2/result.hpp>

#include <Eigen/Core>

#include <span>
#include <vector>

namespace m3c2::detail {

/// Neighbourhood moments at one scale: count and co-moment matrix sum (v - mean)(v - mean)^T of
/// the neighbours' offsets v from the core point.
struct ScaleMoments {
  std::uint32_t count = 0;
  Eigen::Matrix3d comoment = Eigen::Matrix3d::Zero();
};

struct NormalScratch {
  OctreeScratch octree;
  std::vector<double> offsets;  // the chosen scale's points, for the centred roughness pass
  std::vector<Moments> sums;
  std::vector<ScaleMoments> moments;
  /// Neighbours of the last core point of this thread within the largest sphere (0: unknown or
  /// too few): where they were many, the next core point (its Morton neighbour) skips the count
  /// that only spares sparse neighbourhoods their moments (NormalEstimator::estimate).
  std::uint32_t last_count = 0;
};

/// Moments at every radius of `radii_ascending` (j is within radius r iff squared_distance <=
/// r^2), from one traversal of the octree (octree.hpp): a scale sees exactly its own neighbours,
/// and the sums are a function of that set alone, not of what else the index holds.
void moments_by_scale(const Octree& tree, const Vec3& core, const std::vector<double>& radii_ascending,
                      NormalScratch& scratch);

struct NormalEstimate {
  Vec3 normal = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());  ///< unit, not oriented
  double diameter = std::numeric_limits<double>::quiet_NaN();
  double roughness = std::numeric_limits<double>::quiet_NaN();
  std::uint32_t count = 0;
  PointStatus status = PointStatus::kTooFewNormalPoints;
};

/// Estimates normals of one cloud with params.normal_diameters, choosing the scale by
/// params.scale_selection when there are several. Immutable; estimate() is thread-safe.
class NormalEstimator {
 public:
  NormalEstimator(const Octree& tree, const Params& params);
  NormalEstimate estimate(const Vec3& core, NormalScratch& scratch) const;

 private:
  const Octree& tree_;
  std::vector<double> diameters_;  // ascending, unique
  std::vector<double> radii_;
  std::uint32_t min_points_;
  ScaleSelection selection_;
  Variance variance_;
};

/// Roughness sqrt(lambda3) of the co-moment divided by n - 1 (kSample) or n (kPopulation).
double plane_roughness(double smallest_eigenvalue_of_comoment, std::uint32_t n, Variance variance);

/// Whether lambda3 of the co-moment is too small against lambda1 for its rounding to leave
/// sigma(D) accurate: below kCentredRatio, sigma(D) is recomputed by a centred pass over the
/// points (docs/algorithm.md#3.3). The summed moments' lambda3 is off by about 6e-17 lambda1
/// (measured on planes at UTM coordinates, D 1 and 16), so sigma(D)'s relative error is about
/// 3e-17 / ratio: below 1e-9 above this threshold (test_roughness_precision.cpp). It was 1e-4, which
/// sent most core points of smooth terrain at large D (ratios 1e-5 to 1e-4) through a second pass
/// over every neighbour for an accuracy of 1e-12.
inline constexpr double kCentredRatio = 1e-7;
bool roughness_needs_centred_pass(const Eigen::Vector3d& ascending_eigenvalues);

/// sigma(D) by a second, centred pass over the points' offsets (3 per point, key order, summed
/// in that order): their mean, the plane of their centred co-moment (`normal` where it has none)
/// and sqrt(sum h_j^2 / (n - 1 or n)), h_j the centred offsets along that plane's normal. Its
/// rounding is ~eps of the offsets' spread whatever sigma(D): no eigenvalue of a summed co-moment,
/// and the Rayleigh quotient differs from lambda3 only to second order in the normal's error.
double centred_roughness(std::span<const double> offsets, const Vec3& normal, Variance variance);

}  // namespace m3c2::detail
