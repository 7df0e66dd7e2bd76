#include "index/octree.hpp"

#include "index/cylinder_leaf.hpp"
#include "index/morton.hpp"
#include "index/radix_sort.hpp"
#include "index/rows_in_place.hpp"
#include "support/assert.hpp"
#include "support/number_text.hpp"
#include "support/parallel_for.hpp"
#include "support/portable.hpp"

#include <m3c2/errors.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>

namespace m3c2::detail {
namespace {

using Key = Uint128;  // 3 x 42 bits (portable.hpp)

// A node splits when it holds more than kLeafSize points, or more than kSmallLeafSize within
// 4 x 4 x 4 cells: sparse clouds get few, large leaves (fewer nodes per query) and dense ones
// leaves of one cell, whose crossing points are summed without keys. Measured against a plain
// 32: W1 -7 %, W3 -9 %, W6 -8 %, W2 unchanged (docs/performance.md).
constexpr std::uint32_t kLeafSize = 64;
constexpr std::uint32_t kSmallLeafSize = 16;
// Cell coordinates within +-2^40 are biased so that they are non-negative and fit 42 bits per
// axis: three axes interleave into one 126-bit Morton key. The bias is 2^41 plus the alternating
// bits 0101...01 below 2^40, not a power of two: with a power of two, cells -1 and 0 differed in
// every bit, so a cloud straddling a coordinate plane through the origin (local and scanner
// coordinates, a surface around z = 0) varied in the top bit and took 128-bit keys. With these
// bits, cells c and c' (c < c') cross a multiple of 2^k only where c' - c > 2^k / 3 about, so
// the bits that vary follow the cloud's extent in cells wherever it lies, and a cloud of up to
// about 2^20 cells a side takes 64-bit keys (sorted half as fast, 8 B a point less).
constexpr int kAxisBits = 42;
constexpr std::int64_t kRangeCells = std::int64_t(1) << (kAxisBits - 2);  // |cell| below it
constexpr std::int64_t kBias = (std::int64_t(1) << (kAxisBits - 1)) + 0x5555555555;
static_assert(0x5555555555 < kRangeCells && kBias - kRangeCells > 0 &&
                  kBias + kRangeCells < (std::int64_t(1) << kAxisBits),
              "every cell within the range is biased into [0, 2^42)");
// The depth bound every traversal relies on. A node's level is the highest digit (bit of the
// cell coordinates) at which its keys differ, so at most kAxisBits - 1 at the root, and -1 for a
// leaf of one cell; a child's keys share the digit at which its parent split, so its level is
// lower. A path from the root to a leaf thus has at most kAxisBits + 1 nodes.
constexpr int kMaxPathNodes = kAxisBits + 1;
static_assert(3 * kAxisBits <= 128, "three axes' cells interleave into one 128-bit key (morton_key)");
static_assert(3 * 21 <= 64, "low_morton_key: 21 bits per axis in 64");
// A depth-first traversal pops a node and stacks at most its 8 children: with the at most 7
// siblings still stacked for each node above it on the path, at most 7 (kMaxPathNodes - 2) + 8.
constexpr int kTraversalStack = 8 * kMaxPathNodes;
static_assert(kTraversalStack >= 7 * (kMaxPathNodes - 2) + 8, "traversal stack below its depth bound");
constexpr double kBlockDiameters = 1024.0;
// The nodes' boxes and moments (bound_nodes, sum_moments): each leaf's from its points, on the
// build's threads in blocks of this many nodes (a leaf's value does not depend on which thread
// computes it), then each inner node's from its children's, on the calling thread, from the
// last node to the root (children follow their parent in the array): every merge in one order.
constexpr std::size_t kNodeBlock = 1024;
// The keys and the copy of the coordinates: blocks of this many points.
constexpr std::size_t kPointBlock = std::size_t(1) << 15;
// Box tests that prune use this relative margin (as kdtree.cpp) so that rounding can never drop
// a point the exact per-point test keeps; the "inside" test needs none (see farthest_distance2).
constexpr double kRelativeMargin = 1e-9;

double nearest_distance2(const std::array<double, 3>& lo, const std::array<double, 3>& hi, const Vec3& c) {
  double d2 = 0.0;
  for (int a = 0; a < 3; ++a) {
    // At most one of the two is positive (lo <= hi): no branch to mispredict.
    const double gap = std::max(std::max(lo[a] - c(a), c(a) - hi[a]), 0.0);
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

Key morton_key(const CellKey& u) {
  Key low = 0, high = 0;
  for (int a = 0; a < 3; ++a) {
    low |= Key(spread_bits(std::uint64_t(u[a]))) << a;
    high |= Key(spread_bits(std::uint64_t(u[a]) >> 21)) << a;
  }
  return low | high << 63;
}

/// The low 63 bits of morton_key(u): the whole key of a cloud whose cells differ only in their
/// low 21 bits per axis (most clouds: 2^21 cells of D/16 on each axis).
std::uint64_t low_morton_key(const CellKey& u) {
  return spread_bits(std::uint64_t(u[0])) | spread_bits(std::uint64_t(u[1])) << 1 |
         spread_bits(std::uint64_t(u[2])) << 2;
}

/// The digit (level) at which two Morton keys first differ, -1 when equal.
template <class K>
int differing_level(K a, K b) {
  return a == b ? -1 : highest_bit(a ^ b) / 3;
}

/// The digit (level) at which cell keys a and b first differ, -1 when equal.
int differing_level(const CellKey& a, const CellKey& b) {
  const std::uint64_t x = std::uint64_t((a[0] ^ b[0]) | (a[1] ^ b[1]) | (a[2] ^ b[2]));
  return x ? 63 - std::countl_zero(x) : -1;
}

}  // namespace

OctreeGrid octree_grid(double smallest_scale, double largest_normal_diameter) {
  OctreeGrid grid;
  int exponent = 0;
  // Cells of D/16 hold ~40 points of a 10,000 points/m^2 survey: the fewest node visits and
  // crossing points per neighbourhood of those measured (D/8, D/16, D/32, D/64; docs/performance.md).
  std::frexp(smallest_scale / 16.0, &exponent);  // smallest/16 in [2^(e-1), 2^e)
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

double OctreeGrid::max_abs_coordinate() const { return std::ldexp(cell, kAxisBits - 2); }

void require_within_grid(const char* what, PointsView points, OctreeGrid grid) {
  const double limit = grid.max_abs_coordinate();
  for (std::size_t i = 0; i < points.size(); ++i)
    for (int a = 0; a < 3; ++a)
      if (!(std::abs(points.coord(i, a)) < limit))
        throw InvalidArgument(
            std::string(what) + " has a coordinate (" + number_text(points.coord(i, a), 6) + ") beyond +-" +
            number_text(limit, 6) + ", the range of the spatial index for these scales (2^40 cells of " +
            number_text(grid.cell, 6) + "); remove far outliers or shift the coordinates to a local origin");
}

inline CellKey Octree::cell_of(const double* p) const {
  CellKey k;
  for (int a = 0; a < 3; ++a) {
    // floor() without the library call: the constructor checked |x| < 2^40, so the truncation
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

Octree::Octree(PointsView points, OctreeGrid grid, const OctreeOptions& options)
    : points_(points), grid_(grid), inverse_cell_(1.0 / grid.cell), order_in_place_(options.order_cloud_in_place) {
  if (points.size() >= std::numeric_limits<std::uint32_t>::max())
    throw InvalidArgument("a cloud has " + std::to_string(points.size()) +
                          " points; one spatial index holds at most 4294967294: process the clouds in tiles "
                          "(parameter tile_size)");
  require_within_grid(options.cloud_name, points, grid);
  if (points.empty()) return;
  RunOptions run;
  run.threads = options.build_threads;
  const std::size_t n = points.size();
  std::vector<std::uint64_t> low(n);
  // Each block's smallest and largest cell, then the cloud's: the same for any thread count.
  std::vector<std::array<CellKey, 2>> ranges((n + kPointBlock - 1) / kPointBlock);
  parallel_blocks<int>(
      n, run,
      [&](std::size_t begin, std::size_t end, int&) {
        CellKey lo, hi;
        lo.fill(std::numeric_limits<std::int64_t>::max());
        hi.fill(std::numeric_limits<std::int64_t>::min());
        for (std::size_t i = begin; i < end; ++i) {
          const auto u = cell_of(points_.data() + 3 * i);
          low[i] = low_morton_key(u);
          for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], u[a]), hi[a] = std::max(hi[a], u[a]);
        }
        ranges[begin / kPointBlock] = {lo, hi};
      },
      kPointBlock);
  CellKey lo = ranges[0][0], hi = ranges[0][1];
  for (const auto& r : ranges)
    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], r[0][a]), hi[a] = std::max(hi[a], r[1][a]);
  std::vector<std::uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  // Every key lies between the smallest and the largest cell, so only the bits below their
  // highest differing bit vary: sorted on those alone, in 64 bits where they fit.
  if (differing_level(lo, hi) < 21) {
    sort_in_place(low.data(), order.data(), n, run);
    build(std::move(low), order, options.node_moments, run);
    return;
  }
  low = {};
  std::vector<Key> keys(n);
  parallel_blocks<int>(
      n, run,
      [&](std::size_t begin, std::size_t end, int&) {
        for (std::size_t i = begin; i < end; ++i) keys[i] = morton_key(cell_of(points_.data() + 3 * i));
      },
      kPointBlock);
  sort_in_place(keys.data(), order.data(), n, run);
  build(std::move(keys), order, options.node_moments, run);
}

template <class K>
void Octree::build(std::vector<K>&& keys, std::vector<std::uint32_t>& order, bool node_moments, const RunOptions& run) {
  const std::size_t n = keys.size();
  // Children of a node are stored together, in key order, so the tree is one flat array. A node
  // is split at the digit its keys first differ at (the radix tree), when it holds too many
  // points (kLeafSize) or spans several blocks (moments are per block).
  // Reserved for 0.5 nodes per point, above what clouds take (surfaces up to 0.22, volumes up to
  // 0.35 at about a point per cell; W5: 0.158) since the pages not reached stay unmapped: growing
  // the array by doubling held the old and the new one at once, on both clouds, which was the
  // in-place build's peak (docs/performance.md, memory; m3c2::IndexMemory counts on it).
  nodes_.reserve(n / 2 + 64);
  nodes_.push_back({{}, {}, 0, std::uint32_t(n)});
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    Node node = nodes_[k];
    node.level = std::int8_t(differing_level(keys[node.begin], keys[node.end - 1]));
    M3C2_ASSERT(node.level < kAxisBits, "a node's level is a digit of the 42-bit cell coordinates");
    node.in_block = node.level + 1 <= grid_.block_level;
    const std::uint32_t held = node.end - node.begin;
    if (node.level >= 0 && (held > kLeafSize || (held > kSmallLeafSize && node.level <= 1) || !node.in_block)) {
      node.first_child = std::uint32_t(nodes_.size());
      const int shift = 3 * node.level;
      std::uint32_t begin = node.begin;
      while (begin < node.end) {
        const auto d = std::uint32_t(keys[begin] >> shift) & 7u;
        const auto end =
            std::uint32_t(std::partition_point(keys.begin() + begin, keys.begin() + node.end,
                                               [&](K x) { return (std::uint32_t(x >> shift) & 7u) <= d; }) -
                          keys.begin());
        M3C2_ASSERT(end > begin && differing_level(keys[begin], keys[end - 1]) < node.level,
                    "a child's level is below its parent's (the depth bound)");
        nodes_.push_back({{}, {}, begin, end});
        node.child_mask |= std::uint8_t(1u << d);
        ++node.children;
        begin = end;
      }
    }
    nodes_[k] = node;
  }
  // The keys are done with: freed before the copy of the coordinates is made, so that a cloud's
  // build never holds both (8 B per point less at its peak; docs/performance.md, memory).
  std::vector<K>().swap(keys);
  index_.original = std::move(order);
  order_coordinates(run);
  bound_nodes(run);
  if (node_moments) sum_moments(run);
}

void Octree::add_moments(int threads) {
  if (nodes_.empty() || !moments_.empty()) return;
  RunOptions run;
  run.threads = threads;
  sum_moments(run);
}

void Octree::sum_moments(const RunOptions& run) {
  // Each leaf's cells and their branchings from its points' cells (cell_of, as a query's leaf
  // computes them): the digit at which two cells first differ is that of their Morton keys.
  moments_.resize(nodes_.size());
  struct LeafScratch {
    FoldStack stack;
    std::vector<std::uint32_t> slots;
    std::vector<CellKey> cells;
  };
  parallel_blocks<LeafScratch>(
      nodes_.size(), run,
      [&](std::size_t first, std::size_t last, LeafScratch& s) {
        for (std::size_t k = first; k < last; ++k) {
          const Node& node = nodes_[k];
          if (!node.in_block || node.first_child != 0) continue;
          s.slots.resize(node.end - node.begin);
          std::iota(s.slots.begin(), s.slots.end(), node.begin);
          s.cells.resize(node.end - node.begin);
          for (std::uint32_t i = node.begin; i < node.end; ++i) s.cells[i - node.begin] = cell_of(slot_xyz(i));
          const CellKey* cell = s.cells.data() - node.begin;
          const auto level = [cell](std::uint32_t a, std::uint32_t b) { return differing_level(cell[a], cell[b]); };
          moments_[k] =
              radix_fold(s.slots.data(), node.end - node.begin, level, block_corner(slot_xyz(node.begin)), s.stack);
        }
      },
      kNodeBlock);
  for (std::size_t k = nodes_.size(); k-- > 0;) {
    const Node& node = nodes_[k];
    if (!node.in_block || node.first_child == 0) continue;
    for (std::uint32_t c = node.first_child; c < node.first_child + node.children; ++c)
      merge_into(moments_[k], moments_[c]);
  }
}

void Octree::order_coordinates(const RunOptions& run) {
  const std::vector<std::uint32_t>& index = index_.original;
  const std::size_t n = index.size();
  if (order_in_place_) {
    // Row i goes to the slot s with index[s] = i: the inverse permutation, in the keys' memory.
    std::vector<std::uint32_t> dest(n);
    for (std::size_t s = 0; s < n; ++s) dest[index[s]] = std::uint32_t(s);
    auto* own = const_cast<double*>(points_.data());  // the caller's own array (the constructor's contract)
    move_rows_in_place(own, dest.data(), 0, n);
    index_.reordered = own;
    xyz_ = own;
    return;
  }
  copy_.resize(3 * n);
  // A gather in key order: random reads when the input is not spatially ordered, so each is
  // requested well ahead of its use.
  constexpr std::size_t kAhead = 32;
  parallel_blocks<int>(
      n, run,
      [&](std::size_t begin, std::size_t end, int&) {
        for (std::size_t s = begin; s < end; ++s) {
          if (s + kAhead < end) prefetch(points_.data() + 3 * std::size_t(index[s + kAhead]));
          for (int a = 0; a < 3; ++a) copy_[3 * s + a] = points_.coord(index[s], a);
        }
      },
      kPointBlock);
  xyz_ = copy_.data();
}

SlotIndex::SlotIndex(SlotIndex&& other) noexcept
    : original(std::move(other.original)), reordered(std::exchange(other.reordered, nullptr)) {}

SlotIndex& SlotIndex::operator=(SlotIndex&& other) noexcept {
  if (this != &other) {
    restore();
    original = std::move(other.original);
    reordered = std::exchange(other.reordered, nullptr);
  }
  return *this;
}

SlotIndex::~SlotIndex() { restore(); }

void SlotIndex::restore() noexcept {
  // Slot s's row goes back to row original[s] (which ends as the identity: the index is done).
  if (reordered) move_rows_in_place(reordered, original.data(), 0, original.size());
  reordered = nullptr;
}

void Octree::bound_nodes(const RunOptions& run) {
  const auto empty_box = [](Node& node) {
    node.lo.fill(std::numeric_limits<double>::infinity());
    node.hi.fill(-std::numeric_limits<double>::infinity());
  };
  parallel_blocks<int>(
      nodes_.size(), run,
      [&](std::size_t first, std::size_t last, int&) {
        for (std::size_t k = first; k < last; ++k) {
          Node& node = nodes_[k];
          if (node.first_child != 0) continue;
          empty_box(node);
          for (std::uint32_t s = node.begin; s < node.end; ++s)
            for (int a = 0; a < 3; ++a)
              node.lo[a] = std::min(node.lo[a], slot_xyz(s)[a]), node.hi[a] = std::max(node.hi[a], slot_xyz(s)[a]);
        }
      },
      kNodeBlock);
  for (std::size_t k = nodes_.size(); k-- > 0;) {
    Node& node = nodes_[k];
    if (node.first_child == 0) continue;
    empty_box(node);
    for (std::uint32_t c = node.first_child; c < node.first_child + node.children; ++c)
      for (int a = 0; a < 3; ++a)
        node.lo[a] = std::min(node.lo[a], nodes_[c].lo[a]), node.hi[a] = std::max(node.hi[a], nodes_[c].hi[a]);
  }
}

DescentCache::Path& DescentCache::path_for(const Octree* tree) {
  static_assert(std::tuple_size_v<decltype(Path::node)> >= kMaxPathNodes, "a path holds a root-to-leaf path");
  for (int k = 0; k < 2; ++k)
    if (paths_[k].tree == tree) return paths_[last_ = k];
  last_ = 1 - last_;  // replace the path used least recently
  paths_[last_] = Path{};
  paths_[last_].tree = tree;
  return paths_[last_];
}

std::uint32_t Octree::covering_node(const std::array<double, 3>& lo, const std::array<double, 3>& hi,
                                    DescentCache* cache) const {
  // Core points are not range-checked like the clouds: a box beyond the grid starts at the root.
  const double limit = grid_.max_abs_coordinate();
  for (int a = 0; a < 3; ++a)
    if (!(std::abs(lo[a]) < limit && std::abs(hi[a]) < limit)) return 0;
  // Every point of the box has its cell between the two corners' cells on each axis, so it
  // shares their key digits above `box_level`. Following those digits down the radix tree
  // keeps every such point in the node reached; a node whose own common digits contradict
  // them holds none.
  const CellKey klo = cell_of(lo.data()), khi = cell_of(hi.data());
  const int box_level = differing_level(klo, khi);
  DescentCache::Path* path = cache ? &cache->path_for(this) : nullptr;
  int depth = 0;
  std::uint32_t n = 0;
  if (path && path->size > 0) {
    // The last descent branched at each node of its path by the digit of its own corner; where
    // that digit is also this corner's (levels above `shared`), this descent takes the same child.
    const int shared = differing_level(klo, path->klo);
    while (depth + 1 < path->size) {
      const int level = nodes_[path->node[depth]].level;
      if (level <= box_level || level <= shared) break;
      ++depth;
    }
    n = path->node[depth];
  }
  bool empty = false;
  while (nodes_[n].level > box_level && nodes_[n].first_child != 0) {
    const Node& node = nodes_[n];
    const auto wanted = std::uint8_t(((klo[0] >> node.level) & 1) | ((klo[1] >> node.level) & 1) << 1 |
                                     ((klo[2] >> node.level) & 1) << 2);
    // The child is found from the node's own mask: no child's cache line is read to look.
    if (!(node.child_mask >> wanted & 1u)) {
      empty = true;
      break;
    }
    n = node.first_child + std::uint32_t(std::popcount(unsigned(node.child_mask) & ((1u << wanted) - 1u)));
    M3C2_ASSERT(depth + 1 < kMaxPathNodes, "a descent path is a root-to-leaf path");
    if (path) path->node[++depth] = n;
  }
  if (path) path->node[0] = 0, path->size = depth + 1, path->klo = klo;
  if (empty) return kNoNode;
  // One check of the common digits the branchings did not test, at the node reached: a node on
  // the way whose digits contradict the box's passes the contradiction on to its descendants.
  const Node& node = nodes_[n];
  if (differing_level(cell_of(slot_xyz(node.begin)), klo) > std::max<int>(node.level, box_level)) return kNoNode;
  return n;
}

std::uint32_t Octree::covering_node(const Vec3& centre, double radius, DescentCache* cache) const {
  if (nodes_.empty()) return kNoNode;
  // A point within the radius passes squared_distance() <= r^2, so each of its coordinates
  // lies within r (plus rounding, far below this slack) of the centre's.
  const double slack = kRelativeMargin * (centre.cwiseAbs().maxCoeff() + radius);
  std::array<double, 3> lo, hi;
  for (int a = 0; a < 3; ++a) lo[a] = centre(a) - radius - slack, hi[a] = centre(a) + radius + slack;
  return covering_node(lo, hi, cache);
}

bool Octree::ball_holds(const Vec3& centre, double radius, std::uint32_t n, DescentCache* cache) const {
  if (n == 0) return true;
  const std::uint32_t start = covering_node(centre, radius, cache);
  if (start == kNoNode) return false;
  const double r2 = radius * radius, prune_r2 = r2 * (1.0 + kRelativeMargin) + 1e-300;
  // Depth first; a node is stacked only when its box reaches the sphere, and a stacked leaf's
  // points are requested from memory at once.
  const auto reaches = [&](const Node& node) { return nearest_distance2(node.lo, node.hi, centre) <= prune_r2; };
  std::uint32_t stack[kTraversalStack];  // the depth bound above
  int top = 0;
  if (reaches(nodes_[start])) stack[top++] = start;
  std::uint32_t found = 0;
  while (top > 0) {
    const Node& node = nodes_[stack[--top]];
    if (farthest_distance2(node.lo, node.hi, centre) <= r2) {
      found += node.end - node.begin;
    } else if (node.first_child == 0) {
      for (std::uint32_t s = node.begin; s < node.end; ++s) found += squared_distance(slot_xyz(s), centre) <= r2;
    } else {
      for (std::uint32_t c = node.first_child; c < node.first_child + node.children; ++c)
        if (reaches(nodes_[c])) {
          M3C2_ASSERT(top < kTraversalStack, "the traversal stack's depth bound");
          if (nodes_[c].first_child == 0) prefetch(slot_xyz(nodes_[c].begin));
          stack[top++] = c;
        }
    }
    if (found >= n) return true;
  }
  return false;
}

void Octree::ball_runs(const Vec3& centre, double radius, std::vector<std::array<std::uint32_t, 2>>& runs,
                       DescentCache* cache) const {
  const std::uint32_t start = covering_node(centre, radius, cache);
  if (start == kNoNode) return;
  const double r2 = radius * radius, prune_r2 = r2 * (1.0 + kRelativeMargin) + 1e-300;
  std::uint32_t stack[kTraversalStack];  // the depth bound above
  int top = 0;
  stack[top++] = start;
  while (top > 0) {
    const Node& node = nodes_[stack[--top]];
    if (nearest_distance2(node.lo, node.hi, centre) > prune_r2) continue;
    if (node.first_child != 0 && farthest_distance2(node.lo, node.hi, centre) > r2) {
      M3C2_ASSERT(top + int(node.children) <= kTraversalStack, "the traversal stack's depth bound");
      for (std::uint32_t k = node.children; k-- > 0;) stack[top++] = node.first_child + k;  // key order
      continue;
    }
    // A leaf crossing the sphere, or a node inside it: nodes taken in key order often follow
    // each other in the slots, and a run of them is one loop for the caller.
    if (!runs.empty() && runs.back()[1] == node.begin)
      runs.back()[1] = node.end;
    else
      runs.push_back({node.begin, node.end});
  }
}

void Octree::ball_offsets(const Vec3& centre, double radius, std::vector<double>& offsets,
                          OctreeScratch& scratch) const {
  auto& runs = scratch.runs;
  runs.clear();
  ball_runs(centre, radius, runs, &scratch.descent);
  const double r2 = radius * radius;
  for (const auto& [begin, end] : runs) {
    // About half a crossing leaf's points are kept, at random, so no branch per point: each
    // point is written and the end advanced by its test.
    const std::size_t old = offsets.size();
    offsets.resize(old + 3 * std::size_t(end - begin));
    double* out = offsets.data() + old;
    std::size_t kept = 0;
    for (std::uint32_t slot = begin; slot < end; ++slot) {
      const double* p = slot_xyz(slot);
      out[3 * kept] = p[0] - centre.x(), out[3 * kept + 1] = p[1] - centre.y(), out[3 * kept + 2] = p[2] - centre.z();
      kept += squared_distance(p, centre) <= r2;
    }
    offsets.resize(old + 3 * kept);
  }
}

template <class Level>
Moments Octree::radix_fold(const std::uint32_t* slots, std::uint32_t n, Level&& level_between, const Vec3& origin,
                           FoldStack& stack) const {
  // One pass in key order with a stack of the open branchings (their digit, their children's
  // fold so far): a point diverging from the previous one at digit L closes every branching
  // below L, then joins the one at L or opens it. Children are merged in key order, each
  // branching's fold from its first child: exactly the nested fold of octree.hpp.
  stack.clear();
  Moments current;
  for (std::uint32_t i = 0; i < n;) {
    std::uint32_t cell_end = i + 1;
    while (cell_end < n && level_between(slots[cell_end], slots[i]) < 0) ++cell_end;
    // A cell of one point (most cells of a survey sparser than ~64 points per cell face) is
    // two_pass_moments() of it without the loops: mean 0 + (p - origin) (the sum's first add,
    // kept for the sign of zero), co-moment zero, the same bits.
    const Moments cell = cell_end - i == 1 ? one_point_moments(xyz_ + 3 * std::size_t(slots[i]), origin)
                                           : two_pass_moments(xyz_, slots + i, cell_end - i, origin);
    if (i > 0) {
      const int level = level_between(slots[i - 1], slots[i]);
      while (!stack.empty() && stack.back().first < level) {
        merge_into(stack.back().second, current);
        current = stack.back().second;
        stack.pop_back();
      }
      if (!stack.empty() && stack.back().first == level)
        merge_into(stack.back().second, current);
      else
        stack.emplace_back(level, current);
    }
    current = cell;
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
  /// near2: nearest_distance2() of n's box, which the caller computed to skip the nodes outside.
  void node(std::uint32_t n, double near2, std::size_t ka, std::size_t kb, Moments* out, int depth, bool to_centre) {
    const Node& node = tree.nodes_[n];
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
    M3C2_ASSERT(depth + 1 < kMaxPathNodes + 3, "one level of results per node on the path (ball_moments)");
    Moments* fold = level_out(depth + 1);
    std::fill(fold + ka, fold + inside, Moments{});
    if (node.first_child == 0) {
      leaf(n, ka, inside, fold);
    } else {
      for (std::uint32_t c = node.first_child; c < node.first_child + node.children; ++c) {
        const Node& child = tree.nodes_[c];
        const double child_near2 = nearest_distance2(child.lo, child.hi, centre);
        if (child_near2 > prune_r2[inside - 1]) continue;  // outside every sphere asked of it
        this->node(c, child_near2, ka, inside, fold, depth + 1, !node.in_block && child.in_block);
      }
    }
    for (std::size_t k = ka; k < inside; ++k) {
      if (to_centre) fold[k].mean += shift;
      merge_into(out[k], fold[k]);
    }
  }

  /// Writes to s.slots the slots begin + j, j < m, with s.d2[j] <= limit, in order, and returns
  /// their number: no branch per point (about half of a crossing leaf's points are kept).
  std::uint32_t gather_kept(std::uint32_t begin, std::uint32_t m, double limit) {
    s.slots.resize(m);
    std::uint32_t kept = 0;
    for (std::uint32_t j = 0; j < m; ++j) {
      s.slots[kept] = begin + j;
      kept += s.d2[j] <= limit;
    }
    return kept;
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
      if (count == m)
        out[k] = tree.moments_[n];
      else if (count > 0)
        partial_begin = std::min(partial_begin, k), partial_end = k + 1;
    }
    if (partial_begin >= partial_end) return;
    const Vec3 origin = tree.block_corner(tree.slot_xyz(node.begin));
    if (node.level < 0) {
      // One grid cell: its radix fold is the cell's two-pass moments, no keys needed.
      for (std::size_t k = partial_begin; k < partial_end; ++k) {
        const std::uint32_t kept = gather_kept(node.begin, m, r2[k]);
        out[k] = two_pass_moments(tree.xyz_, s.slots.data(), kept, origin);
      }
      return;
    }
    // Several cells: the cells only of the points the widest partial sphere keeps.
    s.keys.resize(m);
    const double widest = r2[partial_end - 1];
    for (std::uint32_t j = 0; j < m; ++j)
      if (s.d2[j] <= widest) s.keys[j] = tree.cell_of(tree.slot_xyz(node.begin + j));
    const CellKey* keys = s.keys.data() - node.begin;
    const auto level = [keys](std::uint32_t a, std::uint32_t b) { return differing_level(keys[a], keys[b]); };
    for (std::size_t k = partial_begin; k < partial_end; ++k) {
      const std::uint32_t kept = gather_kept(node.begin, m, r2[k]);
      out[k] = tree.radix_fold(s.slots.data(), kept, level, origin, s.fold);
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
  // One level of results per node on the path (the depth bound above), plus the caller's.
  if (scratch.stack.size() < (kMaxPathNodes + 3) * scales) scratch.stack.resize((kMaxPathNodes + 3) * scales);
  std::fill(scratch.stack.begin(), scratch.stack.begin() + scales, Moments{});
  // Start at the deepest node holding the largest sphere's box. Its ancestors would only merge
  // its result with empty sets (copies) and, below a node spanning blocks, move it to the
  // centre's frame, which the start node then does itself: the same bits as from the root.
  const std::uint32_t start =
      covering_node(centre, radii_ascending.empty() ? 0.0 : radii_ascending.back(), &scratch.descent);
  if (start != kNoNode)
    q.node(start, nearest_distance2(nodes_[start].lo, nodes_[start].hi, centre), 0, scales, scratch.stack.data(), 0,
           nodes_[start].in_block && !nodes_[0].in_block);
  out.assign(scratch.stack.begin(), scratch.stack.begin() + scales);
}

void Octree::cylinder(const Cylinder& cyl, std::vector<double>& t_out, DescentCache* cache,
                      std::vector<std::uint32_t>* index_out) const {
  t_out.clear();
  if (index_out) index_out->clear();
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
  // Start at the deepest node holding the box: the points inside come out in the same key order.
  const std::uint32_t start = covering_node(box_lo, box_hi, cache);
  if (start == kNoNode) return;
  std::size_t kept = 0;                  // of t_out's values, those of points inside
  std::uint32_t stack[kTraversalStack];  // the depth bound above
  int top = 0;
  stack[top++] = start;
  while (top > 0) {
    const Node& node = nodes_[stack[--top]];
    if (node.lo[0] > box_hi[0] || node.hi[0] < box_lo[0] || node.lo[1] > box_hi[1] || node.hi[1] < box_lo[1] ||
        node.lo[2] > box_hi[2] || node.hi[2] < box_lo[2])
      continue;
    const Vec3 m(0.5 * (node.lo[0] + node.hi[0]), 0.5 * (node.lo[1] + node.hi[1]), 0.5 * (node.lo[2] + node.hi[2]));
    const double extent = 0.5 * Vec3(node.hi[0] - node.lo[0], node.hi[1] - node.lo[1], node.hi[2] - node.lo[2]).norm();
    const Vec3 v = m - c;
    const double s = std::clamp(v.dot(n), cyl.t_min, cyl.t_max);
    const double reach = cyl.radius + extent + slack;
    if ((v - s * n).squaredNorm() > reach * reach) continue;
    if (node.first_child == 0) {
      const std::uint32_t held = node.end - node.begin;
      if (t_out.size() < kept + held) {  // room for every point of the leaf, grown by doubling
        t_out.resize(std::max(kept + held, 2 * t_out.size()));
        if (index_out) index_out->resize(t_out.size());
      }
      kept += cylinder_leaf(slot_xyz(node.begin), held, cyl, r2, t_out.data() + kept,
                            index_out ? index_out->data() + kept : nullptr, index_.original.data() + node.begin);
    } else {
      M3C2_ASSERT(top + int(node.children) <= kTraversalStack, "the traversal stack's depth bound");
      for (std::uint32_t k = node.children; k-- > 0;) stack[top++] = node.first_child + k;  // key order
    }
  }
  t_out.resize(kept);
  if (index_out) index_out->resize(kept);
}

}  // namespace m3c2::detail
