#pragma once
// Spatial index of the M3C2 pipeline: an octree on a grid anchored at the coordinate origin,
// whose nodes carry the moments of their points, so that a normal's neighbourhood (3.1.2) is
// summed from whole nodes and only the nodes crossing the sphere cost per-point work.
//
// Canonical sums. The points are ordered by the Morton key of their cell on the global grid
// (cell side `cell`, a power of two), ties by original index. The moments of a set S are
// defined as a nested fold over the compressed octree (radix tree on those keys) of S itself:
// the points of one grid cell in two passes (moments.hpp), then at each branching the children
// merged in key order (merge_into). A query folds whole nodes inside the sphere and recurses
// into the others; because merging with an empty set copies, the fold over a subtree restricted
// to the sphere equals the fold over the radix tree of the neighbours alone. The moments of a
// neighbourhood are therefore a function of the set of neighbours (and their relative input
// order), whatever else the index holds: a tile sees the same bits as the whole cloud.
//
// Frames. Moments of nodes inside one block (an aligned cell of side cell * 2^block_level, at
// least 1024 largest normal diameters) are taken about the block's corner, which keeps UTM-sized
// coordinates exact (Sterbenz); nodes spanning blocks hold no moments and fold their children's
// after moving them to the core point's frame.

#include "index/cylinder.hpp"
#include "index/distance.hpp"
#include "index/moments.hpp"

#include <m3c2/points_view.hpp>
#include <m3c2/run_options.hpp>

#include <array>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

namespace m3c2::detail {

/// Grid of an octree: finest cell side (a power of two) and the block level.
struct OctreeGrid {
  double cell = 0.0;
  int block_level = 0;

  /// The largest |coordinate| the grid indexes: 2^40 cells (biased into keys of 42 bits per axis).
  double max_abs_coordinate() const;
};

/// Throws InvalidArgument naming `what` when a coordinate of `points` is beyond the grid's range.
void require_within_grid(const char* what, PointsView points, OctreeGrid grid);

/// The grid for a run with these scales (diameters): cells of about min / 16, blocks at least
/// 1024 max wide. Derived from the parameters only, so that every tile of a run shares it.
OctreeGrid octree_grid(double smallest_scale, double largest_normal_diameter);

/// A point's grid cell: floor(coordinate / cell) + the bias (octree.cpp) on each axis.
using CellKey = std::array<std::int64_t, 3>;
/// Open branchings of a radix fold: (digit, fold of the children so far).
using FoldStack = std::vector<std::pair<int, Moments>>;

class Octree;

/// The paths of the last descents to a covering node, one per octree (a core point queries
/// both clouds): a query near the last one (the core points run in Morton order) resumes from
/// the deepest node the two descents share instead of the root. Per thread, like the scratch.
class DescentCache {
 private:
  friend class Octree;
  struct Path {
    const Octree* tree = nullptr;
    CellKey klo{};                         // the box corner's cell the path was taken for
    int size = 0;                          // nodes on the path, the root first
    std::array<std::uint32_t, 48> node{};  // levels fall from at most 41 to -1
  };
  Path& path_for(const Octree* tree);
  std::array<Path, 2> paths_;
  int last_ = 0;
};

struct OctreeScratch {
  DescentCache descent;
  std::vector<double> r2;
  std::vector<Moments> stack;
  std::vector<double> d2;
  std::vector<CellKey> keys;
  std::vector<std::uint32_t> slots;
  std::vector<std::array<std::uint32_t, 2>> runs;  // Octree::ball_runs, for ball_offsets
  FoldStack fold;
};

/// The original index of each slot of an index and, when the index ordered its cloud's own
/// array in place (OctreeOptions::order_cloud_in_place), that array: put back in its original order when
/// this is destroyed, which a failed build does too.
class SlotIndex {
 public:
  SlotIndex() = default;
  SlotIndex(SlotIndex&& other) noexcept;
  SlotIndex& operator=(SlotIndex&& other) noexcept;
  ~SlotIndex();

  std::vector<std::uint32_t> original;  // original index of each slot
  double* reordered = nullptr;          // the cloud's array, in slot order while this lives

 private:
  void restore() noexcept;
};

/// How an Octree is built, beside its points and grid. The results are the same bits for any
/// choice: these trade memory and time, and name the cloud in errors.
struct OctreeOptions {
  /// Sums the node moments that normals read (ball_moments, section 3.1.2); without them an
  /// index answers the other queries and add_moments() adds them later, the same bits.
  bool node_moments = false;
  /// The index orders the cloud's own array in key order instead of copying it (24 B per point
  /// less) and puts it back when destroyed; while it lives, row s of that array is the point of
  /// original index original_index(s). Only for an array the caller owns and nothing else reads
  /// meanwhile (RunOptions::order_clouds_in_place).
  bool order_cloud_in_place = false;
  /// The cloud as the error of a coordinate beyond the grid's range names it ("the reference
  /// cloud"); read during the constructor only.
  const char* cloud_name = "a cloud";
  /// OpenMP threads of the build's parallel phases (the keys, the sort's buckets, the copy, the
  /// leaves' boxes and moments); 0: all.
  int build_threads = 1;
};

class Octree {
 public:
  /// Indexes `points` (kept by reference), built as `options` say. Throws InvalidArgument naming
  /// options.cloud_name when a coordinate is beyond the grid's range.
  Octree(PointsView points, OctreeGrid grid, const OctreeOptions& options = {});

  /// Adds the node moments of normals to an index built without them, on `threads` OpenMP
  /// threads (0: all): the same bits as an index built with them. Nothing if it has them.
  void add_moments(int threads);

  PointsView points() const { return points_; }
  std::size_t size() const { return index_.original.size(); }
  std::uint32_t original_index(std::size_t slot) const { return index_.original[slot]; }

  /// Replaces `t_out` with the axial offsets t of the points inside `cylinder` (the inclusive
  /// test of cylinder.hpp), in key order: the same order in any tile.
  /// `index_out`, if given, receives the points' original indices in the same order.
  void cylinder(const Cylinder& cylinder, std::vector<double>& t_out, DescentCache* cache = nullptr,
                std::vector<std::uint32_t>* index_out = nullptr) const;

  /// Whether at least `n` points lie within `radius` of `centre` (the test of ball_moments),
  /// counted until n are found: a neighbourhood too small for a plane fit costs no moments.
  bool ball_holds(const Vec3& centre, double radius, std::uint32_t n, DescentCache* cache = nullptr) const;

  /// Appends to `offsets` p - centre (3 values) of every point p within `radius` of `centre`
  /// (squared_distance <= r^2, the test of ball_moments), in key order: the same points in the
  /// same order in any tile. The second, centred pass of a roughness (normals.cpp).
  void ball_offsets(const Vec3& centre, double radius, std::vector<double>& offsets, OctreeScratch& scratch) const;

  /// Appends to `runs` the slot ranges [begin, end), in key order and merged where contiguous,
  /// of the nodes that may hold points within `radius` of `centre`: every such point is in a run,
  /// with others near the sphere, so the caller applies squared_distance() <= r^2 itself.
  void ball_runs(const Vec3& centre, double radius, std::vector<std::array<std::uint32_t, 2>>& runs,
                 DescentCache* cache = nullptr) const;
  /// The coordinates of a slot; a run's slots are contiguous (x, y, z, x, ...).
  const double* slot_xyz(std::uint32_t slot) const { return xyz_ + 3 * std::size_t(slot); }

  /// Moments, about any origin, of the points within each radius of `radii_ascending` of
  /// `centre` (squared_distance <= r^2), written to out[k]. Requires the node moments
  /// (OctreeOptions::node_moments, or add_moments()).
  void ball_moments(const Vec3& centre, std::span<const double> radii_ascending, OctreeScratch& scratch,
                    std::vector<Moments>& out) const;

 private:
  struct Node {
    std::array<double, 3> lo, hi;   // bounding box of the node's points
    std::uint32_t begin, end;       // slots
    std::uint32_t first_child = 0;  // children first_child .. first_child + children - 1, key order; 0: a leaf
    std::uint8_t children = 0;
    std::int8_t level = -1;       // the key digit its points first differ at; -1: one grid cell
    bool in_block = true;         // all its points lie in one block
    std::uint8_t child_mask = 0;  // bit d set: a child whose points have digit d at `level`
  };
  struct BallQuery;

  /// The tree over the points in key order: order[s] is the point of slot s, keys[s] its Morton
  /// key. Nodes, their bounding boxes and, `node_moments`, their moments. The keys are freed
  /// once the nodes are split, before the coordinates are copied (the build's peak).
  template <class K>
  void build(std::vector<K>&& keys, std::vector<std::uint32_t>& order, bool node_moments, const RunOptions& run);
  /// The coordinates in key order (slot s: the point index_.original[s]): copied, or the cloud's
  /// own array ordered in place.
  void order_coordinates(const RunOptions& run);
  void bound_nodes(const RunOptions& run);
  void sum_moments(const RunOptions& run);
  /// The deepest node holding every point of the box [lo, hi], or kNoNode when none of its
  /// points lies in the box: a query starts there instead of at the root (octree.cpp).
  /// `cache`, if any, holds the last descent in this tree, resumed where it applies.
  std::uint32_t covering_node(const std::array<double, 3>& lo, const std::array<double, 3>& hi,
                              DescentCache* cache) const;
  /// covering_node() of the box of the sphere of `radius` about `centre`, grown for rounding.
  std::uint32_t covering_node(const Vec3& centre, double radius, DescentCache* cache) const;
  static constexpr std::uint32_t kNoNode = ~std::uint32_t(0);
  CellKey cell_of(const double* p) const;
  Vec3 block_corner(const double* p) const;
  /// Moments about `origin` of the points of slots[0, n) (ascending): the nested fold over the
  /// radix tree of those points alone. level_between(i, j): the digit at which the cells of slots
  /// i and j first differ, -1 for one cell.
  template <class Level>
  Moments radix_fold(const std::uint32_t* slots, std::uint32_t n, Level&& level_between, const Vec3& origin,
                     FoldStack& stack) const;

  PointsView points_;
  OctreeGrid grid_;
  double inverse_cell_;
  bool order_in_place_;
  std::vector<double> copy_;     // the coordinates in key order, unless ordered in place
  const double* xyz_ = nullptr;  // 3 per slot, in key order: copy_ or the cloud's own array
  SlotIndex index_;
  std::vector<Node> nodes_;
  std::vector<Moments> moments_;  // per node, about its block's corner (in-block nodes only)
};

}  // namespace m3c2::detail
