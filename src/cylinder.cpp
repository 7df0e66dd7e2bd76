#include "cylinder.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace m3c2::detail {

void cylinder_offsets(const KdTree& tree, const Cylinder& cyl, CylinderScratch& scratch,
                      std::vector<double>& t_out) {
  t_out.clear();
  scratch.hits.clear();
  const double length = cyl.t_max - cyl.t_min;
  const double r2 = cyl.radius * cyl.radius;
  const auto segments = static_cast<std::size_t>(std::max(1.0, std::ceil(length / (2.0 * cyl.radius))));
  const double seg_len = length / double(segments);
  // Inflated so that rounding can never drop a point the cylinder test keeps: the relative term
  // covers the ball test, the absolute one the rounding of the segment centre core + m n, which
  // is an absolute coordinate (about 1e-9 at a UTM northing of 5e6).
  const double magnitude = cyl.core.cwiseAbs().maxCoeff();
  const double centre_rounding = 8.0 * std::numeric_limits<double>::epsilon() * magnitude;
  const double ball_r = std::sqrt(r2 + 0.25 * seg_len * seg_len) * (1.0 + 1e-9) + centre_rounding + 1e-12;
  const PointsView pts = tree.points();

  for (std::size_t s = 0; s < segments; ++s) {
    const double lo = cyl.t_min + double(s) * seg_len;
    const double hi = (s + 1 == segments) ? cyl.t_max : cyl.t_min + double(s + 1) * seg_len;
    const bool last = s + 1 == segments;
    const Vec3 centre = cyl.core + (0.5 * (lo + hi)) * cyl.normal;
    scratch.candidates.clear();
    tree.ball(centre, ball_r, scratch.candidates);
    for (const std::uint32_t i : scratch.candidates) {
      const double vx = pts.coord(i, 0) - cyl.core.x();
      const double vy = pts.coord(i, 1) - cyl.core.y();
      const double vz = pts.coord(i, 2) - cyl.core.z();
      const double t = vx * cyl.normal.x() + vy * cyl.normal.y() + vz * cyl.normal.z();
      if (t < lo || (last ? t > hi : t >= hi)) continue;
      const double wx = vx - t * cyl.normal.x();
      const double wy = vy - t * cyl.normal.y();
      const double wz = vz - t * cyl.normal.z();
      if (wx * wx + wy * wy + wz * wz <= r2) scratch.hits.emplace_back(i, t);
    }
  }
  std::sort(scratch.hits.begin(), scratch.hits.end());
  t_out.reserve(scratch.hits.size());
  for (const auto& [index, t] : scratch.hits) t_out.push_back(t);
}

}  // namespace m3c2::detail
