// M3C2-PM (James, Robson & Smith 2017): the LOD from per-point precisions instead of the
// cylinders' spreads, as CloudCompare's qM3C2 computes it (docs/algorithm.md#m3c2-pm).

#include "uncertainty/uncertainty.hpp"

#include <cmath>
#include <limits>

namespace m3c2::detail {

namespace {

/// ||(nx sx, ny sy, nz sz)||^2 of point j: its precision "projected on the normal" as qM3C2 does
/// (the standard deviation along n when the axes' errors are perfectly correlated in sign).
double projected2(std::span<const double> precision, std::uint32_t j, const Vec3& n) {
  const double* s = precision.data() + 3 * std::size_t(j);
  const double a = n.x() * s[0], b = n.y() * s[1], c = n.z() * s[2];
  return a * a + b * b + c * c;
}

}  // namespace

double precision_sigma(PointsView cloud, std::span<const double> precision, std::span<const std::uint32_t> points,
                       const Vec3& normal, double scale, PrecisionRule rule) {
  if (points.empty()) return std::numeric_limits<double>::quiet_NaN();
  if (rule == PrecisionRule::kAllPoints) {
    double sum = 0.0;
    for (const std::uint32_t j : points) sum += projected2(precision, j, normal);
    return scale * std::sqrt(sum / double(points.size()));
  }
  // The point nearest the points' centre of gravity (qM3C2's ComputePMUncertainty); the first
  // of equally near points in the cylinder's key order, the same in any tile. The centre is
  // summed about the first point, which keeps georeferenced coordinates exact.
  const Vec3 origin = cloud[points[0]];
  Vec3 sum = Vec3::Zero();
  for (const std::uint32_t j : points) sum += cloud[j] - origin;
  const Vec3 centre = sum / double(points.size());
  std::uint32_t nearest = points[0];
  double best = std::numeric_limits<double>::infinity();
  for (const std::uint32_t j : points) {
    const double d2 = (cloud[j] - origin - centre).squaredNorm();
    if (d2 < best) best = d2, nearest = j;
  }
  return scale * std::sqrt(projected2(precision, nearest, normal));
}

}  // namespace m3c2::detail
