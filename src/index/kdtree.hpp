#pragma once
// Spatial index over one cloud for the C2C baselines: ball queries with exact, inclusive
// boundaries. The M3C2 pipeline uses octree.hpp.

#include "index/distance.hpp"

#include <m3c2/points_view.hpp>

#include <array>
#include <cstdint>
#include <limits>
#include <vector>

namespace m3c2::detail {

/// Immutable kd-tree over a cloud for fixed-radius balls. The points are copied once in leaf
/// order, so a query reads contiguous memory whatever the order of the input; the copies are
/// the same float64 values, so membership is exactly that of the input coordinates. Queries are
/// const and may run concurrently from any number of threads.
class KdTree {
 public:
  explicit KdTree(PointsView points);

  /// The caller's points, by original index.
  PointsView points() const { return points_; }

  /// Appends the original indices of the points with squared_distance <= radius^2 (tree order).
  void ball(const Vec3& centre, double radius, std::vector<std::uint32_t>& out) const;

  static constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
  /// The original index of the point nearest `q` within `max_distance` (squared_distance <=
  /// max_distance^2; the first in tree order on a tie), or kNone. Thread-safe.
  std::uint32_t nearest(const Vec3& q, double max_distance) const;

  /// Appends the original indices of the points `keep(p)` accepts (p: the point's 3 coordinates,
  /// the input's float64 values), visiting only the nodes whose box `prune(lo, hi)` does not
  /// reject (tree order). `prune` must be conservative: it may reject a box only when `keep`
  /// would reject every point in it.
  template <class Prune, class Keep>
  void select(Prune&& prune, Keep&& keep, std::vector<std::uint32_t>& out) const {
    visit(prune, [&](std::uint32_t s, const double* p) {
      if (keep(p)) out.push_back(index_[s]);
    });
  }

 private:
  struct Node {
    std::array<double, 3> lo, hi;  // bounding box of the node's points
    std::uint32_t begin, end;      // slots
    std::uint32_t left = 0;        // children: left and left + 1 (0 for a leaf)
  };
  void build(std::vector<std::uint32_t>& order);
  template <class Prune, class Accept>
  void visit(Prune&& prune, Accept&& accept) const {
    if (nodes_.empty()) return;
    std::uint32_t stack[128];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const Node& node = nodes_[stack[--top]];
      if (prune(node.lo, node.hi)) continue;
      if (node.left == 0) {
        for (std::uint32_t s = node.begin; s < node.end; ++s) accept(s, xyz_.data() + 3 * std::size_t(s));
      } else {
        stack[top++] = node.left + 1;
        stack[top++] = node.left;
      }
    }
  }

  PointsView points_;
  std::vector<double> xyz_;           // 3 per slot, in leaf order
  std::vector<std::uint32_t> index_;  // original index of each slot
  std::vector<Node> nodes_;
};

}  // namespace m3c2::detail
