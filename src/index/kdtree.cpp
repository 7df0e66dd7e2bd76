#include "index/kdtree.hpp"

#include <m3c2/errors.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>

namespace m3c2::detail {
namespace {

constexpr std::uint32_t kLeafSize = 24;

// Boxes are compared with a margin so that rounding in a box test can never prune a node
// holding a point the exact per-point test keeps; the per-point tests alone decide membership.
constexpr double kRelativeMargin = 1e-9;

double box_distance2(const std::array<double, 3>& lo, const std::array<double, 3>& hi, const Vec3& c) {
  double d2 = 0.0;
  for (int a = 0; a < 3; ++a) {
    const double below = lo[a] - c(a), above = c(a) - hi[a];
    const double gap = below > 0.0 ? below : above > 0.0 ? above : 0.0;
    d2 += gap * gap;
  }
  return d2;
}

}  // namespace

KdTree::KdTree(PointsView points) : points_(points) {
  if (points.size() >= std::numeric_limits<std::uint32_t>::max())
    throw InvalidArgument("a cloud has " + std::to_string(points.size()) +
                          " points; one spatial index holds at most 4294967294: process the clouds in tiles "
                          "(parameter tile_size)");
  if (points.empty()) return;
  std::vector<std::uint32_t> order(points.size());
  std::iota(order.begin(), order.end(), 0u);
  build(order);
  index_ = std::move(order);
  xyz_.resize(3 * index_.size());
  for (std::size_t s = 0; s < index_.size(); ++s)
    for (int a = 0; a < 3; ++a) xyz_[3 * s + a] = points.coord(index_[s], a);
}

void KdTree::build(std::vector<std::uint32_t>& order) {
  // Breadth-first median splits on the widest axis; children of node k are stored together,
  // so the tree is one flat array. Ties are broken by original index: the build is
  // deterministic for a given input.
  nodes_.reserve(2 * (order.size() / kLeafSize + 1));
  nodes_.push_back({{}, {}, 0, std::uint32_t(order.size()), 0});
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    Node node = nodes_[k];
    node.lo.fill(std::numeric_limits<double>::infinity());
    node.hi.fill(-std::numeric_limits<double>::infinity());
    for (std::uint32_t s = node.begin; s < node.end; ++s)
      for (int a = 0; a < 3; ++a) {
        const double v = points_.coord(order[s], a);
        node.lo[a] = std::min(node.lo[a], v), node.hi[a] = std::max(node.hi[a], v);
      }
    if (node.end - node.begin > kLeafSize) {
      int axis = 0;
      for (int a = 1; a < 3; ++a)
        if (node.hi[a] - node.lo[a] > node.hi[axis] - node.lo[axis]) axis = a;
      const std::uint32_t mid = node.begin + (node.end - node.begin) / 2;
      std::nth_element(order.begin() + node.begin, order.begin() + mid, order.begin() + node.end,
                       [&](std::uint32_t i, std::uint32_t j) {
                         const double a = points_.coord(i, axis), b = points_.coord(j, axis);
                         return a < b || (a == b && i < j);
                       });
      node.left = std::uint32_t(nodes_.size());
      nodes_.push_back({{}, {}, node.begin, mid, 0});
      nodes_.push_back({{}, {}, mid, node.end, 0});
    }
    nodes_[k] = node;
  }
}

void KdTree::ball(const Vec3& centre, double radius, std::vector<std::uint32_t>& out) const {
  const double r2 = radius * radius, prune_r2 = r2 * (1.0 + kRelativeMargin) + 1e-300;
  visit([&](const auto& lo, const auto& hi) { return box_distance2(lo, hi, centre) > prune_r2; },
        [&](std::uint32_t s, const double* p) {
          if (squared_distance(p, centre) <= r2) out.push_back(index_[s]);
        });
}

std::uint32_t KdTree::nearest(const Vec3& q, double max_distance) const {
  // Balls growing by 4 from max_distance / 64: the nearest point within a ball is the nearest of
  // all, and a small first ball spares most of the tree when the point is close (ICP's pairs
  // after its first steps, a segment's own surface). In each ball the traversal prunes every box
  // farther than the best point so far; select() appends each improvement, so the last is the nearest.
  thread_local std::vector<std::uint32_t> found;
  for (double radius = max_distance / 64.0;; radius = std::min(4.0 * radius, max_distance)) {
    double best2 = radius * radius;
    bool any = false;
    found.clear();
    select([&](const auto& lo, const auto& hi) { return box_distance2(lo, hi, q) > best2 * (1.0 + kRelativeMargin); },
           [&](const double* p) {
             const double d2 = squared_distance(p, q);
             if (d2 > best2 || (any && d2 == best2)) return false;
             best2 = d2, any = true;
             return true;
           },
           found);
    if (!found.empty()) return found.back();
    if (radius >= max_distance) return kNone;
  }
}

}  // namespace m3c2::detail
