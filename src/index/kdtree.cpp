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
  // Depth first, the nearer child first (by its box's distance), each box pruned when it lies
  // farther than the best point so far: the first leaves reached are those around q, so the best
  // distance falls at once and most of the tree is never read. The answer is the point of least
  // squared distance within max_distance, the lowest slot (tree order) on a tie: whatever order
  // the leaves are read in, so the same point as any exact search that breaks ties so.
  if (nodes_.empty()) return kNone;
  double best2 = max_distance * max_distance;
  std::uint32_t best = kNone;  // a slot
  struct Pending {
    std::uint32_t node;
    double d2;  // its box's squared distance to q
  };
  Pending stack[128];  // two per level: 2 x ceil(log2(2^32 / kLeafSize)) < 128
  int top = 0;
  stack[top++] = {0, box_distance2(nodes_[0].lo, nodes_[0].hi, q)};
  while (top > 0) {
    const Pending pending = stack[--top];
    if (pending.d2 > best2 * (1.0 + kRelativeMargin)) continue;
    const Node& node = nodes_[pending.node];
    if (node.left == 0) {
      for (std::uint32_t s = node.begin; s < node.end; ++s) {
        const double d2 = squared_distance(xyz_.data() + 3 * std::size_t(s), q);
        if (d2 < best2 || (d2 == best2 && s < best)) best2 = d2, best = s;
      }
      continue;
    }
    const Pending left{node.left, box_distance2(nodes_[node.left].lo, nodes_[node.left].hi, q)};
    const Pending right{node.left + 1, box_distance2(nodes_[node.left + 1].lo, nodes_[node.left + 1].hi, q)};
    // The nearer pushed last, read first.
    if (right.d2 < left.d2)
      stack[top++] = left, stack[top++] = right;
    else
      stack[top++] = right, stack[top++] = left;
  }
  return best == kNone ? kNone : index_[best];
}

}  // namespace m3c2::detail
