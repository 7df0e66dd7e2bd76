#pragma once
// ICP's pairs (Chen & Medioni 1992): each sampled compared point, moved by the current estimate,
// paired with its nearest reference point, whose plane (normal at scale D, section 3.1.2) it is
// measured against; and the Gauss-Newton normal equations of those point-to-plane residuals.

#include <m3c2/points_view.hpp>
#include <m3c2/run_options.hpp>

#include "index/kdtree.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

namespace m3c2::detail {

using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

/// A rigid motion about a fixed centre: p' = R (p - centre) + centre + t.
struct Pose {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Vec3 translation = Vec3::Zero();
  Vec3 centre = Vec3::Zero();
  Vec3 apply(const Vec3& p) const { return rotation * (p - centre) + centre + translation; }
};

/// The reference as ICP's targets: the points whose neighbourhood of diameter D has a plane,
/// with its unit normal, in a k-d tree (a point without a plane is never a target).
class Targets {
 public:
  Targets(PointsView reference, double normal_diameter, const RunOptions& run);
  /// The nearest target to `q` within `max_distance` (the first in tree order on a tie); kNone if none.
  std::uint32_t nearest(const Vec3& q, double max_distance) const;
  Vec3 point(std::uint32_t i) const { return {xyz_[3 * i], xyz_[3 * i + 1], xyz_[3 * i + 2]}; }
  Vec3 normal(std::uint32_t i) const { return {normals_[3 * i], normals_[3 * i + 1], normals_[3 * i + 2]}; }
  std::size_t size() const { return xyz_.size() / 3; }

  static constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();

 private:
  std::vector<double> xyz_, normals_;  // the targets, 3 values each
  std::unique_ptr<KdTree> tree_;       // over xyz_
};

/// The compared points ICP pairs: every `stride`-th, `count` of them.
struct Sources {
  PointsView compared;
  std::size_t stride = 1, count = 0;
  Vec3 operator[](std::size_t j) const { return compared[j * stride]; }
};

/// Each source's target (Targets::kNone: unpaired) and signed residual n . (q' - p) (NaN: unpaired).
struct Pairing {
  std::vector<std::uint32_t> target;
  std::vector<double> residual;
};

void pair_sources(const Targets& targets, const Sources& sources, const Pose& pose, double max_distance, Pairing& out,
                  const RunOptions& run);

/// J^T J, J^T r and sum r^2 over the pairs whose residual is in [low, high], J's row of a pair
/// being d r / d (w, t) = ((q' - centre) x n, n) for a rotation w about the centre after the pose
/// and a shift t. Summed in fixed blocks, then the blocks in order: the same bits for any thread count.
struct NormalEquations {
  Matrix6d jtj = Matrix6d::Zero();
  Vector6d jtr = Vector6d::Zero();
  double sum_squares = 0.0;
  std::uint64_t pairs = 0;
};

NormalEquations normal_equations(const Targets& targets, const Sources& sources, const Pose& pose,
                                 const Pairing& pairing, double low, double high, const RunOptions& run);

}  // namespace m3c2::detail
