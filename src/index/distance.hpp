#pragma once
// The one squared distance of the engine: every membership test of a sphere uses it.

#include <m3c2/points_view.hpp>

namespace m3c2::detail {

/// Squared distance between (x, y, z) and `c`, computed the one way used everywhere.
inline double squared_distance(const double* p, const Vec3& c) {
  const double dx = p[0] - c.x(), dy = p[1] - c.y(), dz = p[2] - c.z();
  return dx * dx + dy * dy + dz * dz;
}
inline double squared_distance(PointsView points, std::size_t i, const Vec3& c) {
  return squared_distance(points.data() + 3 * i, c);
}

}  // namespace m3c2::detail
