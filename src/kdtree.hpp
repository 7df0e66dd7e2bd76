#pragma once
// Spatial index over one cloud: ball and cylinder queries with exact, inclusive boundaries.

#include <m3c2/points_view.hpp>

#include <array>
#include <cstdint>
#include <vector>

namespace m3c2::detail {

/// Squared distance between (x, y, z) and `c`, computed the one way used everywhere.
inline double squared_distance(const double* p, const Vec3& c) {
  const double dx = p[0] - c.x(), dy = p[1] - c.y(), dz = p[2] - c.z();
  return dx * dx + dy * dy + dz * dz;
}
inline double squared_distance(PointsView points, std::size_t i, const Vec3& c) {
  return squared_distance(points.data() + 3 * i, c);
}

/// The projection cylinder of section 3.1.3: axis through `core` along the unit `normal`,
/// radius `radius` (d / 2), axial offsets t in [t_min, t_max]. Both boundaries are inclusive:
/// p is inside iff |v - t n|^2 <= radius^2 and t_min <= t <= t_max, with v = p - core and
/// t = v . n, computed in that order in float64 (docs/algorithm.md#boundaries).
struct Cylinder {
  Vec3 core;
  Vec3 normal;
  double radius = 0.0;
  double t_min = 0.0;
  double t_max = 0.0;
};

/// Immutable kd-tree over a cloud, built for the two queries of M3C2: fixed-radius balls
/// (normals) and cylinders (projection). The points are copied once in leaf order, so a query
/// reads contiguous memory whatever the order of the input; the copies are the same float64
/// values, so membership and every statistic are exactly those of the input coordinates.
/// Differences of nearby coordinates are exact (Sterbenz), so UTM-sized inputs lose nothing.
/// Queries are const and may run concurrently from any number of threads.
class KdTree {
 public:
  explicit KdTree(PointsView points);

  /// The caller's points, by original index.
  PointsView points() const { return points_; }

  /// Appends the original indices of the points with squared_distance <= radius^2 (tree order).
  void ball(const Vec3& centre, double radius, std::vector<std::uint32_t>& out) const;

  /// Appends (original index << 32 | slot) of the points in the ball, for callers that sort by
  /// original index and then read coordinates with slot_xyz().
  void ball_keys(const Vec3& centre, double radius, std::vector<std::uint64_t>& out) const;

  /// Appends (original index, t) of the points inside `cylinder`.
  void cylinder(const Cylinder& cylinder, std::vector<std::pair<std::uint32_t, double>>& out) const;

  /// Coordinates of the point stored in `slot` (x, y, z).
  const double* slot_xyz(std::uint32_t slot) const { return xyz_.data() + 3 * std::size_t(slot); }

 private:
  struct Node {
    std::array<double, 3> lo, hi;  // bounding box of the node's points
    std::uint32_t begin, end;      // slots
    std::uint32_t left = 0;        // children: left and left + 1 (0 for a leaf)
  };
  void build(std::vector<std::uint32_t>& order);
  template <class Prune, class Accept>
  void visit(Prune&& prune, Accept&& accept) const;

  PointsView points_;
  std::vector<double> xyz_;            // 3 per slot, in leaf order
  std::vector<std::uint32_t> index_;   // original index of each slot
  std::vector<Node> nodes_;
};

}  // namespace m3c2::detail
