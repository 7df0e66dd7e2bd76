#include "normals.hpp"

#include "plane_fit.hpp"

#include <algorithm>
#include <cmath>

namespace m3c2::detail {
namespace {

/// Smaller is more planar. kMostPlanar: the paper's lambda3 share (3.2). kCloudCompare: minus
/// its score 2 s0 + 4 s1 - 2, s_k the squared eigenvalues' shares, largest first.
double planarity_cost(const Eigen::Vector3d& ascending, ScaleSelection selection) {
  const double l1 = std::max(ascending(2), 0.0), l2 = std::max(ascending(1), 0.0),
               l3 = std::max(ascending(0), 0.0);
  if (selection == ScaleSelection::kMostPlanar) return l3 / (l1 + l2 + l3);
  const double sum2 = l1 * l1 + l2 * l2 + l3 * l3;
  return -(2.0 * (l1 * l1 / sum2) + 4.0 * (l2 * l2 / sum2) - 2.0);
}

/// Sorts point indices ascending: LSD radix sort on 11-bit digits, as many passes as indices
/// below `point_count` need.
void sort_indices(std::vector<std::uint32_t>& keys, std::vector<std::uint32_t>& buffer, std::size_t point_count) {
  buffer.resize(keys.size());
  for (int shift = 0; shift < 32 && ((point_count - 1) >> shift) != 0; shift += 11) {
    std::uint32_t count[2049] = {};
    for (const std::uint32_t k : keys) ++count[((k >> shift) & 2047u) + 1];
    for (int b = 0; b < 2048; ++b) count[b + 1] += count[b];
    for (const std::uint32_t k : keys) buffer[count[(k >> shift) & 2047u]++] = k;
    keys.swap(buffer);
  }
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
  sort_indices(s.indices, s.sort_buffer, tree.points().size());
  const PointsView pts = tree.points();
  const std::size_t shells = radii_ascending.size();
  s.moments.assign(shells, ScaleMoments{});
  s.shell_sum.assign(shells, Vec3::Zero());
  auto offset = [&](std::uint32_t i) {
    return Vec3(pts.coord(i, 0) - core.x(), pts.coord(i, 1) - core.y(), pts.coord(i, 2) - core.z());
  };
  auto add_comoment = [](Eigen::Matrix3d& m, const Vec3& d) {
    m(0, 0) += d.x() * d.x(), m(0, 1) += d.x() * d.y(), m(0, 2) += d.x() * d.z();
    m(1, 1) += d.y() * d.y(), m(1, 2) += d.y() * d.z(), m(2, 2) += d.z() * d.z();
  };
  if (shells == 1) {  // one scale: two passes about the mean, nothing else to keep
    for (const std::uint32_t i : s.indices) s.shell_sum[0] += offset(i);
    s.moments[0].count = std::uint32_t(s.indices.size());
    if (!s.indices.empty()) s.shell_sum[0] /= double(s.indices.size());
    for (const std::uint32_t i : s.indices) add_comoment(s.moments[0].comoment, offset(i) - s.shell_sum[0]);
    s.moments[0].comoment = s.moments[0].comoment.selfadjointView<Eigen::Upper>();
    return;
  }
  s.shell.resize(s.indices.size());
  for (std::size_t j = 0; j < s.indices.size(); ++j) {
    const Vec3 v = offset(s.indices[j]);
    const double d2 = v.x() * v.x() + v.y() * v.y() + v.z() * v.z();
    std::size_t k = 0;
    while (d2 > radii_ascending[k] * radii_ascending[k]) ++k;  // the ball query bounds k < shells
    s.shell[j] = static_cast<std::uint16_t>(k);
    s.shell_sum[k] += v;
    ++s.moments[k].count;
  }
  for (std::size_t k = 0; k < shells; ++k)
    if (s.moments[k].count) s.shell_sum[k] /= double(s.moments[k].count);  // now the shell's mean
  for (std::size_t j = 0; j < s.indices.size(); ++j)
    add_comoment(s.moments[s.shell[j]].comoment, offset(s.indices[j]) - s.shell_sum[s.shell[j]]);
  // Cumulative merge, inside out: moments[k] becomes that of the whole ball of radius k.
  Vec3 mean = s.shell_sum[0];
  for (std::size_t k = 1; k < shells; ++k) {
    const double na = s.moments[k - 1].count, nb = s.moments[k].count, n = na + nb;
    if (nb > 0.0) {
      const Vec3 delta = s.shell_sum[k] - mean;
      s.moments[k].comoment += s.moments[k - 1].comoment + (na * nb / n) * (delta * delta.transpose());
      mean += delta * (nb / n);
    } else {
      s.moments[k].comoment = s.moments[k - 1].comoment;
    }
    s.moments[k].count += s.moments[k - 1].count;
  }
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
  }
  return best;
}

}  // namespace m3c2::detail
