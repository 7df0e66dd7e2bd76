#pragma once
// Spatial index over one cloud: fixed-radius ball queries with an exact, inclusive boundary.

#include <m3c2/points_view.hpp>

#include <cstdint>
#include <memory>
#include <vector>

namespace m3c2::detail {

/// Immutable kd-tree over `points` (not copied: they must outlive the tree). Queries are const
/// and may run concurrently from any number of threads.
///
/// Membership is decided here, not by nanoflann: a point p is in the ball of centre c and radius
/// r iff (p - c).squaredNorm() <= r * r, computed componentwise in float64 from the original
/// coordinates. Differences of nearby coordinates are exact (Sterbenz), so UTM-sized inputs lose
/// nothing, and a point exactly on the sphere is always inside, whatever the tree's own rounding.
class KdTree {
 public:
  explicit KdTree(PointsView points);
  ~KdTree();
  KdTree(const KdTree&) = delete;
  KdTree& operator=(const KdTree&) = delete;

  PointsView points() const { return points_; }

  /// Appends to `out` the indices of the points within `radius` of `centre` (inclusive), in the
  /// tree's traversal order. `out` is not cleared.
  void ball(const Vec3& centre, double radius, std::vector<std::uint32_t>& out) const;

 private:
  struct Impl;
  PointsView points_;
  std::unique_ptr<Impl> impl_;
};

/// Squared distance between point i of `points` and `c`, computed the one way used everywhere.
inline double squared_distance(PointsView points, std::size_t i, const Vec3& c) {
  const double dx = points.coord(i, 0) - c.x();
  const double dy = points.coord(i, 1) - c.y();
  const double dz = points.coord(i, 2) - c.z();
  return dx * dx + dy * dy + dz * dz;
}

}  // namespace m3c2::detail
