#include "pipeline/normals.hpp"

#include "pipeline/plane_fit.hpp"

#include <algorithm>
#include <cmath>

namespace m3c2::detail {
namespace {

// Neighbours of the previous core point, in multiples of min_points, above which the count
// before the moments is skipped (NormalEstimator::estimate).
constexpr std::uint32_t kDenseAfter = 4;

/// Smaller is more planar. kMostPlanar: the paper's lambda3 share (3.2). kCloudCompare: minus
/// its score 2 s0 + 4 s1 - 2, s_k the squared eigenvalues' shares, largest first. kPy4dgeo: minus
/// py4dgeo's planarity (lambda2 - lambda3) / lambda1.
double planarity_cost(const Eigen::Vector3d& ascending, ScaleSelection selection) {
  const double l1 = std::max(ascending(2), 0.0), l2 = std::max(ascending(1), 0.0), l3 = std::max(ascending(0), 0.0);
  if (selection == ScaleSelection::kMostPlanar) return l3 / (l1 + l2 + l3);
  if (selection == ScaleSelection::kPy4dgeo) return -(l2 - l3) / l1;
  const double sum2 = l1 * l1 + l2 * l2 + l3 * l3;
  return -(2.0 * (l1 * l1 / sum2) + 4.0 * (l2 * l2 / sum2) - 2.0);
}

}  // namespace

double plane_roughness(double smallest_eigenvalue_of_comoment, std::uint32_t n, Variance variance) {
  const double denom = variance == Variance::kSample ? double(n) - 1.0 : double(n);
  return std::sqrt(std::max(smallest_eigenvalue_of_comoment, 0.0) / denom);
}

bool roughness_needs_centred_pass(const Eigen::Vector3d& ascending) {
  return !(ascending(0) >= kCentredRatio * ascending(2));
}

double centred_roughness(std::span<const double> offsets, const Vec3& normal, Variance variance) {
  const std::size_t n = offsets.size() / 3;
  const double denom = variance == Variance::kSample ? double(n) - 1.0 : double(n);
  if (!(denom > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  const auto point = [&](std::size_t j) { return Vec3(offsets[3 * j], offsets[3 * j + 1], offsets[3 * j + 2]); };
  Vec3 mean = Vec3::Zero();
  for (std::size_t j = 0; j < n; ++j) mean += point(j);
  mean /= double(n);
  // The plane of the centred points themselves: the summed moments' normal can be off by
  // ~1e-10 rad (their rounding), which the Rayleigh quotient below would feel at sigma ~ 1e-10 D.
  Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
  for (std::size_t j = 0; j < n; ++j) {
    const Vec3 v = point(j) - mean;
    c.noalias() += v * v.transpose();
  }
  const PlaneFit fit = fit_plane(c);
  const Vec3 axis = fit.degenerate ? normal : fit.normal;
  double ss = 0.0;
  for (std::size_t j = 0; j < n; ++j) {
    const double h = (point(j) - mean).dot(axis);
    ss += h * h;
  }
  return std::sqrt(ss / denom);
}

void moments_by_scale(const Octree& tree, const Vec3& core, const std::vector<double>& radii_ascending,
                      NormalScratch& s) {
  tree.ball_moments(core, radii_ascending, s.octree, s.sums);
  s.moments.resize(s.sums.size());
  for (std::size_t k = 0; k < s.sums.size(); ++k) {
    const auto& c = s.sums[k].comoment;
    s.moments[k].count = static_cast<std::uint32_t>(s.sums[k].count);
    s.moments[k].comoment << c[0], c[1], c[2], c[1], c[3], c[4], c[2], c[4], c[5];
  }
}

NormalEstimator::NormalEstimator(const Octree& tree, const Params& params)
    : tree_(tree), diameters_(params.normal_diameters), selection_(params.scale_selection), variance_(params.variance) {
  std::sort(diameters_.begin(), diameters_.end());
  diameters_.erase(std::unique(diameters_.begin(), diameters_.end()), diameters_.end());
  for (const double d : diameters_) radii_.push_back(0.5 * d);
  min_points_ = diameters_.size() > 1 ? std::max(params.min_points_multiscale, params.min_points_normal)
                                      : params.min_points_normal;
}

NormalEstimate NormalEstimator::estimate(const Vec3& core, NormalScratch& scratch) const {
  // Fewer than min_points within the largest sphere: too few at every scale (the common case
  // on sparse clouds), known from a count that stops at min_points. Where the last core point
  // had many neighbours the count is skipped: its answer would almost surely be yes, and the
  // moments say the same when it is no (every scale below min_points: the estimate stays {}),
  // so the result does not depend on the skip, only the time.
  if (radii_.empty()) return {};
  const bool likely_dense = scratch.last_count >= kDenseAfter * std::max(min_points_, 1u);
  if (!likely_dense && !tree_.ball_holds(core, radii_.back(), min_points_, &scratch.octree.descent)) {
    scratch.last_count = 0;
    return {};
  }
  moments_by_scale(tree_, core, radii_, scratch);
  scratch.last_count = scratch.moments.back().count;
  NormalEstimate best;
  bool best_centred = false;  // sigma(D) of `best` needs the centred pass
  double best_cost = std::numeric_limits<double>::infinity();
  // From the largest scale down, replacing only on a strictly better cost: ties keep the
  // larger, smoother scale.
  for (std::size_t k = radii_.size(); k-- > 0;) {
    const ScaleMoments& m = scratch.moments[k];
    if (m.count < min_points_) continue;
    const PlaneFit fit = fit_plane(m.comoment);
    if (fit.degenerate) {
      if (best.status == PointStatus::kTooFewNormalPoints) best.status = PointStatus::kDegenerateNormal;
      continue;
    }
    const double cost = planarity_cost(fit.eigenvalues, selection_);
    if (best.status == PointStatus::kOk && !(cost < best_cost)) continue;
    best_cost = cost;
    best = {fit.normal, diameters_[k], plane_roughness(fit.eigenvalues(0), m.count, variance_), m.count,
            PointStatus::kOk};
    best_centred = roughness_needs_centred_pass(fit.eigenvalues);
  }
  if (best.status == PointStatus::kOk && best_centred) {
    scratch.offsets.clear();
    tree_.ball_offsets(core, 0.5 * best.diameter, scratch.offsets, scratch.octree);
    best.roughness = centred_roughness(scratch.offsets, best.normal, variance_);
  }
  return best;
}

}  // namespace m3c2::detail
