#include "normals.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>

namespace m3c2::detail {
namespace {

// Neighbourhoods whose middle eigenvalue is below this share of the largest are lines or single
// points: the plane, hence the normal, is undefined there.
constexpr double kCollinearRatio = 1e-12;

struct ScaleFit {
  Vec3 normal;
  Eigen::Vector3d eigenvalues;  // ascending, of the co-moment matrix
  bool degenerate = true;
};

ScaleFit fit_plane(const ScaleMoments& m) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(m.comoment);
  ScaleFit fit;
  fit.eigenvalues = solver.eigenvalues();
  fit.normal = solver.eigenvectors().col(0).normalized();
  const double largest = fit.eigenvalues(2);
  fit.degenerate = !(largest > 0.0) || !(fit.eigenvalues(1) > kCollinearRatio * largest) ||
                   !fit.normal.allFinite();
  return fit;
}

/// Smaller is more planar. kMostPlanar: the paper's lambda3 share (3.2). kCloudCompare: minus
/// its score 2 s0 + 4 s1 - 2, s_k the squared eigenvalues' shares, largest first.
double planarity_cost(const Eigen::Vector3d& ascending, ScaleSelection selection) {
  const double l1 = std::max(ascending(2), 0.0), l2 = std::max(ascending(1), 0.0),
               l3 = std::max(ascending(0), 0.0);
  if (selection == ScaleSelection::kMostPlanar) return l3 / (l1 + l2 + l3);
  const double sum2 = l1 * l1 + l2 * l2 + l3 * l3;
  return -(2.0 * (l1 * l1 / sum2) + 4.0 * (l2 * l2 / sum2) - 2.0);
}

}  // namespace

double plane_roughness(double smallest_eigenvalue_of_comoment, std::uint32_t n, Variance variance) {
  const double denom = variance == Variance::kSample ? double(n) - 1.0 : double(n);
  return std::sqrt(std::max(smallest_eigenvalue_of_comoment, 0.0) / denom);
}

void moments_by_scale(const KdTree& tree, const Vec3& core, const std::vector<double>& radii_ascending,
                      NormalScratch& s) {
  s.indices.clear();
  tree.ball(core, radii_ascending.back(), s.indices);
  const PointsView pts = tree.points();
  s.by_distance.clear();
  for (const std::uint32_t i : s.indices) s.by_distance.emplace_back(squared_distance(pts, i, core), i);
  std::sort(s.by_distance.begin(), s.by_distance.end());

  s.moments.assign(radii_ascending.size(), ScaleMoments{});
  std::size_t scale = 0;
  std::uint32_t n = 0;
  Vec3 mean = Vec3::Zero();
  Eigen::Matrix3d comoment = Eigen::Matrix3d::Zero();
  auto close_scales_below = [&](double d2) {
    while (scale < radii_ascending.size() && d2 > radii_ascending[scale] * radii_ascending[scale])
      s.moments[scale++] = {n, comoment};
  };
  for (const auto& [d2, i] : s.by_distance) {
    close_scales_below(d2);
    const Vec3 v(pts.coord(i, 0) - core.x(), pts.coord(i, 1) - core.y(), pts.coord(i, 2) - core.z());
    ++n;
    const Vec3 delta = v - mean;
    mean += delta / double(n);
    const Vec3 after = v - mean;
    for (int a = 0; a < 3; ++a)
      for (int b = a; b < 3; ++b) comoment(a, b) += delta(a) * after(b);
  }
  close_scales_below(std::numeric_limits<double>::infinity());
  for (auto& m : s.moments) m.comoment = m.comoment.selfadjointView<Eigen::Upper>();
}

NormalEstimator::NormalEstimator(const KdTree& tree, const Params& params)
    : tree_(tree),
      diameters_(params.normal_diameters),
      selection_(params.scale_selection),
      variance_(params.variance) {
  std::sort(diameters_.begin(), diameters_.end());
  diameters_.erase(std::unique(diameters_.begin(), diameters_.end()), diameters_.end());
  for (const double d : diameters_) radii_.push_back(0.5 * d);
  min_points_ = diameters_.size() > 1 ? std::max(params.min_points_multiscale, params.min_points_normal)
                                      : params.min_points_normal;
}

NormalEstimate NormalEstimator::estimate(const Vec3& core, NormalScratch& scratch) const {
  moments_by_scale(tree_, core, radii_, scratch);
  NormalEstimate best;
  double best_cost = std::numeric_limits<double>::infinity();
  // From the largest scale down, replacing only on a strictly better cost: ties keep the
  // larger, smoother scale.
  for (std::size_t k = radii_.size(); k-- > 0;) {
    const ScaleMoments& m = scratch.moments[k];
    if (m.count < min_points_) continue;
    const ScaleFit fit = fit_plane(m);
    if (fit.degenerate) {
      if (best.status == PointStatus::kTooFewNormalPoints) best.status = PointStatus::kDegenerateNormal;
      continue;
    }
    const double cost = planarity_cost(fit.eigenvalues, selection_);
    if (best.status == PointStatus::kOk && !(cost < best_cost)) continue;
    best_cost = cost;
    best = {fit.normal, diameters_[k], plane_roughness(fit.eigenvalues(0), m.count, variance_), m.count,
            PointStatus::kOk};
  }
  return best;
}

}  // namespace m3c2::detail
