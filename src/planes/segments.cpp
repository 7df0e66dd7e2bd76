// The least-squares plane of each segment (Zahs et al. 2022, 3.3: the segment features).

#include <m3c2/errors.hpp>
#include <m3c2/pbm3c2.hpp>

#include "pipeline/orientation.hpp"
#include "support/parallel_for.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

namespace m3c2 {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// One segment's plane from its points (in point order): the mean, then the centred moments, so
/// the result is exact whatever the coordinates' offset.
void fit_segment(PointsView points, std::span<const std::uint32_t> members, const Orientation& orientation,
                 PlaneSegments& out, std::size_t row) {
  const double n = double(members.size());
  Vec3 mean = Vec3::Zero();
  for (const std::uint32_t j : members) mean += points[j];
  mean /= n;
  Eigen::Matrix3d comoment = Eigen::Matrix3d::Zero();
  for (const std::uint32_t j : members) {
    const Vec3 v = points[j] - mean;
    comoment += v * v.transpose();
  }
  for (int a = 0; a < 3; ++a) out.centroid[3 * row + a] = mean(a);
  if (members.size() < 3) return;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(comoment);  // ascending
  const Eigen::Vector3d values = eigen.eigenvalues();
  // A line (or a point) has no plane: its middle eigenvalue is rounding against the largest.
  if (eigen.info() != Eigen::Success || !(values(1) > 1e-12 * values(2))) return;
  const Vec3 normal = detail::orient(Vec3(eigen.eigenvectors().col(0)), mean, orientation);
  const Vec3 major = eigen.eigenvectors().col(2);
  for (int a = 0; a < 3; ++a) {
    out.normal[3 * row + a] = normal(a);
    out.major_axis[3 * row + a] = major(a);
    out.eigenvalues[3 * row + a] = std::max(values(2 - a), 0.0) / n;
  }
  if (members.size() < 4) return;
  double squares = 0.0;  // the residuals themselves, not lambda3: exact for a smooth plane too
  for (const std::uint32_t j : members) {
    const double h = (points[j] - mean).dot(normal);
    squares += h * h;
  }
  out.roughness[row] = std::sqrt(squares / (n - 3.0));
}

}  // namespace

PlaneSegments plane_segments(PointsView points, std::span<const std::int64_t> labels, const Orientation& orientation,
                             const RunOptions& run) {
  if (labels.size() != points.size())
    throw InvalidArgument("labels must have one value per point: " + std::to_string(labels.size()) + " for " +
                          std::to_string(points.size()) + " points");
  if (points.size() > UINT32_MAX)
    throw InvalidArgument("plane_segments indexes at most 2^32 - 1 points, got " + std::to_string(points.size()));
  for (std::size_t i = 0; i < points.size(); ++i)
    for (int a = 0; a < 3; ++a)
      if (!std::isfinite(points.coord(i, a)))
        throw InvalidArgument("point " + std::to_string(i) + " has a non-finite coordinate");
  // The members of each segment, in point order: (label, index) sorted.
  std::vector<std::uint32_t> order;
  for (std::size_t i = 0; i < labels.size(); ++i)
    if (labels[i] >= 0) order.push_back(std::uint32_t(i));
  std::stable_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return labels[a] < labels[b]; });
  std::vector<std::size_t> starts;
  PlaneSegments out;
  for (std::size_t k = 0; k < order.size(); ++k)
    if (k == 0 || labels[order[k]] != labels[order[k - 1]]) starts.push_back(k), out.label.push_back(labels[order[k]]);
  starts.push_back(order.size());
  const std::size_t segments = out.label.size();
  out.count.resize(segments);
  out.centroid.assign(3 * segments, kNaN);
  out.normal.assign(3 * segments, kNaN);
  out.eigenvalues.assign(3 * segments, kNaN);
  out.major_axis.assign(3 * segments, kNaN);
  out.roughness.assign(segments, kNaN);
  detail::parallel_blocks<int>(
      segments, run,
      [&](std::size_t begin, std::size_t end, int&) {
        for (std::size_t s = begin; s < end; ++s) {
          const std::span<const std::uint32_t> members(order.data() + starts[s], starts[s + 1] - starts[s]);
          out.count[s] = members.size();
          fit_segment(points, members, orientation, out, s);
        }
      },
      16);
  return out;
}

}  // namespace m3c2
