#include "octree.hpp"

#include <m3c2/errors.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>

namespace m3c2::detail {
namespace {

__extension__ typedef unsigned __int128 Key;  // GCC and Clang; 3 x 42 bits

constexpr std::uint32_t kLeafSize = 16;
// Cell coordinates are biased by 2^41 so that they are non-negative and fit 42 bits per axis:
// three axes interleave into one 126-bit Morton key.
constexpr int kAxisBits = 42;
constexpr std::int64_t kBias = std::int64_t(1) << (kAxisBits - 1);
constexpr double kBlockDiameters = 1024.0;
// Box tests that prune use this relative margin (as kdtree.cpp) so that rounding can never drop
// a point the exact per-point test keeps; the "inside" test needs none (see farthest_distance2).
constexpr double kRelativeMargin = 1e-9;

double nearest_distance2(const std::array<double, 3>& lo, const std::array<double, 3>& hi, const Vec3& c) {
  double d2 = 0.0;
  for (int a = 0; a < 3; ++a) {
    const double below = lo[a] - c(a), above = c(a) - hi[a];
    const double gap = below > 0.0 ? below : above > 0.0 ? above : 0.0;
    d2 += gap * gap;
  }
  return d2;
}

/// squared_distance() of the box corner farthest from c. Rounding is monotonic, so for every
/// point p of the box, squared_distance(p, c) computed in float64 is at most this value: a box
/// with farthest_distance2 <= r^2 holds only points the per-point test keeps.
double farthest_distance2(const std::array<double, 3>& lo, const std::array<double, 3>& hi, const Vec3& c) {
  double s[3];
  for (int a = 0; a < 3; ++a) {
    const double dl = lo[a] - c(a), dh = hi[a] - c(a);
    s[a] = std::max(dl * dl, dh * dh);
  }
  return s[0] + s[1] + s[2];
}

/// Spreads the low 21 bits of v so that bit k lands on bit 3k.
std::uint64_t spread_bits(std::uint64_t v) {
  v &= 0x1fffffULL;
  v = (v | v << 32) & 0x1f00000000ffffULL;
  v = (v | v << 16) & 0x1f0000ff0000ffULL;
  v = (v | v << 8) & 0x100f00f00f00f00fULL;
  v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
  v = (v | v << 2) & 0x1249249249249249ULL;
  return v;
}

Key morton_key(const CellKey& u) {
  Key low = 0, high = 0;
  for (int a = 0; a < 3; ++a) {
    low |= Key(spread_bits(std::uint64_t(u[a]))) << a;
    high |= Key(spread_bits(std::uint64_t(u[a]) >> 21)) << a;
  }
  return low | high << 63;
}

int highest_bit(Key x) {
  const auto hi = std::uint64_t(x >> 64);
  return hi ? 127 - std::countl_zero(hi) : 63 - std::countl_zero(std::uint64_t(x));
}

/// The digit (level) at which cell keys a and b first differ, -1 when equal.
int differing_level(const CellKey& a, const CellKey& b) {
  const std::uint64_t x = std::uint64_t((a[0] ^ b[0]) | (a[1] ^ b[1]) | (a[2] ^ b[2]));
  return x ? 63 - std::countl_zero(x) : -1;
}

/// Sorts `order` by `keys` (stable: ties keep their order), LSD radix on the low `bits` bits.
void radix_sort(std::vector<Key>& keys, std::vector<std::uint32_t>& order, int bits) {
  constexpr int kDigitBits = 11;
  std::vector<Key> key_buffer(keys.size());
  std::vector<std::uint32_t> order_buffer(order.size());
  for (int shift = 0; shift < bits; shift += kDigitBits) {
    std::vector<std::size_t> count((1u << kDigitBits) + 1, 0);
    constexpr std::size_t kMask = (1u << kDigitBits) - 1;
    for (const Key k : keys) ++count[(std::size_t(k >> shift) & kMask) + 1];
    for (std::size_t b = 1; b < count.size(); ++b) count[b] += count[b - 1];
    for (std::size_t i = 0; i < keys.size(); ++i) {
      const std::size_t slot = count[std::size_t(keys[i] >> shift) & kMask]++;
      key_buffer[slot] = keys[i];
      order_buffer[slot] = order[i];
    }
    keys.swap(key_buffer);
    order.swap(order_buffer);
  }
}

}  // namespace

OctreeGrid octree_grid(double smallest_scale, double largest_normal_diameter) {
  OctreeGrid grid;
  int exponent = 0;
  std::frexp(smallest_scale / 32.0, &exponent);  // smallest/32 in [2^(e-1), 2^e)
  grid.cell = std::ldexp(1.0, exponent - 1);
  // Blocks only keep the moments' coordinates small (about the block corner): 1024 diameters
  // wide they lose nothing measurable (1e-13 m at 1 km), and nodes rarely straddle two.
  // Without normals there are no moments: one block (no forced splits).
  grid.block_level = largest_normal_diameter > 0.0 ? 1 : kAxisBits;
  while (std::ldexp(grid.cell, grid.block_level) < kBlockDiameters * largest_normal_diameter &&
         grid.block_level < kAxisBits)
    ++grid.block_level;
  return grid;
}

double OctreeGrid::max_abs_coordinate() const { return std::ldexp(cell, kAxisBits - 1); }

void require_within_grid(const char* what, PointsView points, OctreeGrid grid) {
  const double limit = grid.max_abs_coordinate();
  for (std::size_t i = 0; i < points.size(); ++i)
    for (int a = 0; a < 3; ++a)
      if (!(std::abs(points.coord(i, a)) < limit))
        throw InvalidArgument(std::string(what) + " has a coordinate (" + std::to_string(points.coord(i, a)) +
                              ") beyond +-" + std::to_string(limit) + ", the range of the spatial index for these "
                              "scales (2^41 cells of " + std::to_string(grid.cell) +
                              "); remove far outliers or shift the coordinates to a local origin");
}

CellKey Octree::cell_of(const double* p) const {
  CellKey k;
  for (int a = 0; a < 3; ++a) {
    // floor() without the library call: the constructor checked |x| < 2^41, so the truncation
    // is exact and only negative non-integers need the step down.
    const double x = p[a] * inverse_cell_;
    const auto t = std::int64_t(x);
    k[a] = t - (double(t) > x) + kBias;
  }
  return k;
}

Vec3 Octree::block_corner(const double* p) const {
  const auto k = cell_of(p);
  Vec3 corner;
  for (int a = 0; a < 3; ++a)
    corner(a) = double(((k[a] >> grid_.block_level) << grid_.block_level) - kBias) * grid_.cell;
  return corner;
}

Octree::Octree(PointsView points, OctreeGrid grid, bool with_moments)
    : points_(points), grid_(grid), inverse_cell_(1.0 / grid.cell) {
  if (points.size() >= std::numeric_limits<std::uint32_t>::max())
    throw InvalidArgument("a cloud has " + std::to_string(points.size()) +
                          " points; one spatial index holds at most 4294967294 (use --tile-size)");
  require_within_grid("a cloud", points, grid);
  if (points.empty()) return;
  std::vector<std::uint32_t> order(points.size());
  std::iota(order.begin(), order.end(), 0u);
  build(order);
  if (with_moments) {
    moments_.resize(nodes_.size());
    std::vector<CellKey> keys;
    FoldStack stack;
    for (std::size_t k = nodes_.size(); k-- > 0;) {
      const Node& node = nodes_[k];
      if (!node.in_block) continue;
      if (node.first_child == 0) {
        keys.clear();
        for (std::uint32_t s = node.begin; s < node.end; ++s) keys.push_back(cell_of(slot_xyz(s)));
        moments_[k] = radix_fold(node.begin, node.end, keys.data() - node.begin, block_corner(slot_xyz(node.begin)),
                                 [](std::uint32_t) { return true; }, stack);
      } else {
        for (std::uint32_t c = node.first_child; c < node.first_child + node.children; ++c)
          merge_into(moments_[k], moments_[c]);
      }
    }
  }
}

void Octree::build(std::vector<std::uint32_t>& order) {
  const std::size_t n = order.size();
  std::vector<Key> keys(n);
  CellKey lo, hi;
  lo.fill(std::numeric_limits<std::int64_t>::max());
  hi.fill(std::numeric_limits<std::int64_t>::min());
  for (std::size_t i = 0; i < n; ++i) {
    const auto u = cell_of(points_.data() + 3 * i);
    keys[i] = morton_key(u);
    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], u[a]), hi[a] = std::max(hi[a], u[a]);
  }
  // Every key lies between the smallest and the largest cell, so only the bits below their
  // highest differing bit vary: sort on those alone.
  const int varying = differing_level(lo, hi) + 1;
  radix_sort(keys, order, 3 * varying);

  index_ = std::move(order);
  xyz_.resize(3 * n);
  for (std::size_t s = 0; s < n; ++s)
    for (int a = 0; a < 3; ++a) xyz_[3 * s + a] = points_.coord(index_[s], a);

  // Children of a node are stored together, in key order, so the tree is one flat array. A node
  // is split at the digit its keys first differ at (the radix tree), when it holds more than
  // kLeafSize points or spans several blocks (moments are per block).
  nodes_.reserve(2 * (n / kLeafSize + 1));
  nodes_.push_back({{}, {}, 0, std::uint32_t(n)});
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    Node node = nodes_[k];
    const Key diff = keys[node.begin] ^ keys[node.end - 1];
    node.level = std::int8_t(diff == 0 ? -1 : highest_bit(diff) / 3);
    node.in_block = node.level + 1 <= grid_.block_level;
    if (node.level >= 0 && (node.end - node.begin > kLeafSize || !node.in_block)) {
      node.first_child = std::uint32_t(nodes_.size());
      const int shift = 3 * node.level;
      std::uint32_t begin = node.begin;
      while (begin < node.end) {
        const auto d = std::uint32_t(keys[begin] >> shift) & 7u;
        const auto end = std::uint32_t(std::partition_point(keys.begin() + begin, keys.begin() + node.end,
                                                            [&](Key x) { return (std::uint32_t(x >> shift) & 7u) <= d; }) -
                                       keys.begin());
        nodes_.push_back({{}, {}, begin, end});
        ++node.children;
        begin = end;
      }
    }
    nodes_[k] = node;
  }
  for (std::size_t k = nodes_.size(); k-- > 0;) {
    Node& node = nodes_[k];
    node.lo.fill(std::numeric_limits<double>::infinity());
    node.hi.fill(-std::numeric_limits<double>::infinity());
    if (node.first_child == 0) {
      for (std::uint32_t s = node.begin; s < node.end; ++s)
        for (int a = 0; a < 3; ++a) node.lo[a] = std::min(node.lo[a], slot_xyz(s)[a]), node.hi[a] = std::max(node.hi[a], slot_xyz(s)[a]);
    } else {
      for (std::uint32_t c = node.first_child; c < node.first_child + node.children; ++c)
        for (int a = 0; a < 3; ++a)
          node.lo[a] = std::min(node.lo[a], nodes_[c].lo[a]), node.hi[a] = std::max(node.hi[a], nodes_[c].hi[a]);
    }
  }
}

template <class Keep>
Moments Octree::radix_fold(std::uint32_t begin, std::uint32_t end, const CellKey* keys, const Vec3& origin, Keep&& keep,
                           FoldStack& stack) const {
  // One pass in key order with a stack of the open branchings (their digit, their children's
  // fold so far): a point diverging from the previous one at digit L closes every branching
  // below L, then joins the one at L or opens it. Children are merged in key order, each
  // branching's fold from its first child: exactly the nested fold of octree.hpp.
  stack.clear();
  Moments current;
  bool any = false;
  std::uint32_t previous = 0;
  for (std::uint32_t i = begin; i < end;) {
    if (!keep(i)) {
      ++i;
      continue;
    }
    std::uint32_t cell_end = i + 1;
    while (cell_end < end && differing_level(keys[cell_end], keys[i]) < 0) ++cell_end;
    const Moments cell = two_pass_moments(xyz_.data(), i, cell_end, origin, keep);
    if (any) {
      const int level = differing_level(keys[previous], keys[i]);
      while (!stack.empty() && stack.back().first < level) {
        merge_into(stack.back().second, current);
        current = stack.back().second;
        stack.pop_back();
      }
      if (!stack.empty() && stack.back().first == level) merge_into(stack.back().second, current);
      else stack.emplace_back(level, current);
    }
    current = cell;
    any = true;
    previous = i;
    i = cell_end;
  }
  while (!stack.empty()) {
    merge_into(stack.back().second, current);
    current = stack.back().second;
    stack.pop_back();
  }
  return current;
}

/// One ball_moments() call: the recursion over the nodes crossing the spheres.
struct Octree::BallQuery {
  const Octree& tree;
  const Vec3& centre;
  std::span<const double> radii;
  OctreeScratch& s;
  std::size_t scales = radii.size();
  const double* r2;        // radius^2 per scale
  const double* prune_r2;  // beyond this a box holds no neighbour

  Moments* level_out(int depth) { return s.stack.data() + std::size_t(depth) * scales; }

  /// Merges into out[k], k in [ka, kb), the moments of node n's points within radius k: in the
  /// frame of n's block, or moved to centre's frame when `to_centre` (n in a block, its parent
  /// spanning blocks). A node inside a sphere gives its stored moments, one outside nothing, and
  /// the others the fold of their children's (or of their points, for a leaf).
  void node(std::uint32_t n, std::size_t ka, std::size_t kb, Moments* out, int depth, bool to_centre) {
    const Node& node = tree.nodes_[n];
    const double near2 = nearest_distance2(node.lo, node.hi, centre);
    while (ka < kb && near2 > prune_r2[ka]) ++ka;  // outside the small spheres
    if (ka == kb) return;
    std::size_t inside = kb;
    if (node.in_block) {
      const double far2 = farthest_distance2(node.lo, node.hi, centre);
      while (inside > ka && far2 <= r2[inside - 1]) --inside;
    }
    const Vec3 shift = to_centre ? Vec3(tree.block_corner(tree.slot_xyz(node.begin)) - centre) : Vec3::Zero();
    for (std::size_t k = inside; k < kb; ++k) {
      if (!to_centre) {
        merge_into(out[k], tree.moments_[n]);
        continue;
      }
      Moments moved = tree.moments_[n];
      moved.mean += shift;
      merge_into(out[k], moved);
    }
    if (ka == inside) return;
    Moments* fold = level_out(depth + 1);
    std::fill(fold + ka, fold + inside, Moments{});
    if (node.first_child == 0) {
      leaf(n, ka, inside, fold);
    } else {
      for (std::uint32_t c = node.first_child; c < node.first_child + node.children; ++c)
        this->node(c, ka, inside, fold, depth + 1, !node.in_block && tree.nodes_[c].in_block);
    }
    for (std::size_t k = ka; k < inside; ++k) {
      if (to_centre) fold[k].mean += shift;
      merge_into(out[k], fold[k]);
    }
  }

  /// A leaf crossing the spheres [ka, kb): per-point distances; a sphere holding some of its
  /// points only folds those over their own radix tree.
  void leaf(std::uint32_t n, std::size_t ka, std::size_t kb, Moments* out) {
    const Node& node = tree.nodes_[n];
    const std::uint32_t m = node.end - node.begin;
    s.d2.resize(m);
    for (std::uint32_t j = 0; j < m; ++j) s.d2[j] = squared_distance(tree.slot_xyz(node.begin + j), centre);
    // Most crossing leaves lie wholly inside or outside each sphere: they need no keys.
    std::size_t partial_begin = kb, partial_end = ka;
    for (std::size_t k = ka; k < kb; ++k) {
      std::uint32_t count = 0;
      for (std::uint32_t j = 0; j < m; ++j) count += s.d2[j] <= r2[k];
      if (count == m) out[k] = tree.moments_[n];
      else if (count > 0) partial_begin = std::min(partial_begin, k), partial_end = k + 1;
    }
    if (partial_begin >= partial_end) return;
    s.keys.clear();
    for (std::uint32_t j = 0; j < m; ++j) s.keys.push_back(tree.cell_of(tree.slot_xyz(node.begin + j)));
    const Vec3 origin = tree.block_corner(tree.slot_xyz(node.begin));
    const double* d2 = s.d2.data() - node.begin;
    for (std::size_t k = partial_begin; k < partial_end; ++k) {
      const double limit = r2[k];
      out[k] = tree.radix_fold(node.begin, node.end, s.keys.data() - node.begin, origin,
                               [&](std::uint32_t i) { return d2[i] <= limit; }, s.fold);
    }
  }
};

void Octree::ball_moments(const Vec3& centre, std::span<const double> radii_ascending, OctreeScratch& scratch,
                          std::vector<Moments>& out) const {
  const std::size_t scales = radii_ascending.size();
  scratch.r2.resize(2 * scales);
  for (std::size_t k = 0; k < scales; ++k) {
    scratch.r2[k] = radii_ascending[k] * radii_ascending[k];
    scratch.r2[scales + k] = scratch.r2[k] * (1.0 + kRelativeMargin) + 1e-300;
  }
  BallQuery q{*this, centre, radii_ascending, scratch, scales, scratch.r2.data(), scratch.r2.data() + scales};
  // One level of results per depth; a branching always lowers the digit, so the depth stays
  // below the key's 42 digits plus the root.
  if (scratch.stack.size() < (kAxisBits + 4) * scales) scratch.stack.resize((kAxisBits + 4) * scales);
  std::fill(scratch.stack.begin(), scratch.stack.begin() + scales, Moments{});
  if (!nodes_.empty()) q.node(0, 0, scales, scratch.stack.data(), 0, false);
  out.assign(scratch.stack.begin(), scratch.stack.begin() + scales);
}

void Octree::cylinder(const Cylinder& cyl, std::vector<double>& t_out) const {
  t_out.clear();
  if (nodes_.empty()) return;
  const Vec3& c = cyl.core;
  const Vec3& n = cyl.normal;
  const double r2 = cyl.radius * cyl.radius;
  // A node is skipped when its bounding sphere (centre m, radius |half extent|) misses the
  // cylinder: the distance from m to the axis segment exceeds r plus that radius.
  const double scale = c.cwiseAbs().maxCoeff() + cyl.radius + std::max(std::abs(cyl.t_min), std::abs(cyl.t_max));
  const double slack = kRelativeMargin * scale;
  // The cylinder's axis-aligned box (the segment grown by r sqrt(1 - n_a^2) along axis a, plus
  // the slack): a cheap first test that rejects most nodes without a square root.
  std::array<double, 3> box_lo, box_hi;
  for (int a = 0; a < 3; ++a) {
    const double e0 = c(a) + cyl.t_min * n(a), e1 = c(a) + cyl.t_max * n(a);
    const double grow = cyl.radius * std::sqrt(std::max(0.0, 1.0 - n(a) * n(a))) + slack;
    box_lo[a] = std::min(e0, e1) - grow, box_hi[a] = std::max(e0, e1) + grow;
  }
  std::uint32_t stack[8 * 128];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& node = nodes_[stack[--top]];
    if (node.lo[0] > box_hi[0] || node.hi[0] < box_lo[0] || node.lo[1] > box_hi[1] || node.hi[1] < box_lo[1] ||
        node.lo[2] > box_hi[2] || node.hi[2] < box_lo[2])
      continue;
    const Vec3 m(0.5 * (node.lo[0] + node.hi[0]), 0.5 * (node.lo[1] + node.hi[1]), 0.5 * (node.lo[2] + node.hi[2]));
    const double extent = 0.5 * Vec3(node.hi[0] - node.lo[0], node.hi[1] - node.lo[1], node.hi[2] - node.lo[2]).norm();
    const Vec3 v = m - c;
    const double s = std::clamp(v.dot(n), cyl.t_min, cyl.t_max);
    if ((v - s * n).norm() > cyl.radius + extent + slack) continue;
    if (node.first_child == 0) {
      for (std::uint32_t slot = node.begin; slot < node.end; ++slot) {
        const double* p = slot_xyz(slot);
        const double vx = p[0] - c.x(), vy = p[1] - c.y(), vz = p[2] - c.z();
        const double t = vx * n.x() + vy * n.y() + vz * n.z();
        if (t < cyl.t_min || t > cyl.t_max) continue;
        const double wx = vx - t * n.x(), wy = vy - t * n.y(), wz = vz - t * n.z();
        if (wx * wx + wy * wy + wz * wz <= r2) t_out.push_back(t);
      }
    } else {
      for (std::uint32_t k = node.children; k-- > 0;) stack[top++] = node.first_child + k;  // key order
    }
  }
}

}  // namespace m3c2::detail
