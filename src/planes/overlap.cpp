// Where the two epochs' segments overlap (include/m3c2/pbm3c2.hpp, docs/pbm3c2.md): the overlap rule's
// votes (each point's nearest point of the other epoch), and how the paired compared plane fits its own
// points over the reference segment's footprint.

#include <m3c2/errors.hpp>
#include <m3c2/pbm3c2.hpp>

#include "index/kdtree.hpp"
#include "support/parallel_for.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <string>
#include <utility>

namespace m3c2 {
namespace {

/// The row of each point's segment in `planes` (-1: no segment, or a segment without a plane).
std::vector<std::int64_t> rows_of(std::span<const std::int64_t> labels, const PlaneSegments& planes, std::size_t n,
                                  const char* what) {
  if (labels.size() != n)
    throw InvalidArgument(std::string(what) + " labels must have one value per point: " +
                          std::to_string(labels.size()) + " for " + std::to_string(n) + " points");
  std::vector<std::int64_t> rows(n, -1);
  for (std::size_t i = 0; i < n; ++i) {
    if (labels[i] < 0) continue;
    const auto at = std::lower_bound(planes.label.begin(), planes.label.end(), labels[i]);
    if (at == planes.label.end() || *at != labels[i])
      throw InvalidArgument(std::string(what) + " label " + std::to_string(labels[i]) + " has no row in its planes");
    const std::size_t row = std::size_t(at - planes.label.begin());
    if (std::isfinite(planes.normal[3 * row])) rows[i] = std::int64_t(row);
  }
  return rows;
}

/// Every point of one cloud, indexed, with its segment's row (-1: none). An unsegmented point is
/// kept: a reference point whose nearest compared point is in no segment has the surface there
/// but no plane to vote for, and must not vote for a farther surface (a roof for the ground).
struct SegmentedPoints {
  SegmentedPoints(PointsView points, const std::vector<std::int64_t>& rows) : row(rows), tree(points) {}
  const std::vector<std::int64_t>& row;
  detail::KdTree tree;
};

double cosine(const PlaneSegments& a, std::size_t i, const PlaneSegments& b, std::size_t j) {
  double c = 0.0;
  for (int k = 0; k < 3; ++k) c += a.normal[3 * i + k] * b.normal[3 * j + k];
  return std::abs(c);
}

/// Each `from` segment's most voted `to` row (-1: no vote): every point of a `from` segment votes
/// for the segment of its nearest segmented `to` point within the radius, behind the angle gate.
std::vector<std::int64_t> votes(PointsView from, const std::vector<std::int64_t>& from_rows,
                                const PlaneSegments& from_planes, const SegmentedPoints& to,
                                const PlaneSegments& to_planes, const CorrespondenceParams& params,
                                const RunOptions& run) {
  const double min_cosine = std::cos(params.max_angle_degrees * std::numbers::pi / 180.0);
  std::vector<std::int64_t> vote(from.size(), -1);
  detail::parallel_blocks<int>(from.size(), run, [&](std::size_t begin, std::size_t end, int&) {
    for (std::size_t i = begin; i < end; ++i) {
      if (from_rows[i] < 0) continue;
      const std::uint32_t k = to.tree.nearest(from[i], params.search_radius);
      if (k == detail::KdTree::kNone || to.row[k] < 0) continue;
      const std::int64_t j = to.row[k];
      if (cosine(from_planes, std::size_t(from_rows[i]), to_planes, std::size_t(j)) >= min_cosine) vote[i] = j;
    }
  });
  // Tally per segment: (from row, to row) sorted, the longest run wins, the lower `to` row on a tie.
  std::vector<std::pair<std::int64_t, std::int64_t>> cast;
  for (std::size_t i = 0; i < vote.size(); ++i)
    if (vote[i] >= 0) cast.emplace_back(from_rows[i], vote[i]);
  std::sort(cast.begin(), cast.end());
  std::vector<std::int64_t> best(from_planes.size(), -1);
  std::vector<std::size_t> most(from_planes.size(), 0);
  for (std::size_t a = 0; a < cast.size();) {
    std::size_t b = a;
    while (b < cast.size() && cast[b] == cast[a]) ++b;
    const std::size_t row = std::size_t(cast[a].first);
    if (b - a > most[row]) most[row] = b - a, best[row] = cast[a].second;
    a = b;
  }
  return best;
}

}  // namespace

SegmentPairs overlapping_segments(PointsView reference, std::span<const std::int64_t> reference_labels,
                                  const PlaneSegments& reference_planes, PointsView compared,
                                  std::span<const std::int64_t> compared_labels, const PlaneSegments& compared_planes,
                                  const CorrespondenceParams& params, const RunOptions& run) {
  if (!(std::isfinite(params.search_radius) && params.search_radius > 0.0))
    throw InvalidArgument("search_radius must be a positive number, got " + std::to_string(params.search_radius));
  if (!(params.max_angle_degrees > 0.0 && params.max_angle_degrees <= 90.0))
    throw InvalidArgument("max_angle_degrees must be in (0, 90], got " + std::to_string(params.max_angle_degrees));
  const std::vector<std::int64_t> ref_rows = rows_of(reference_labels, reference_planes, reference.size(), "reference");
  const std::vector<std::int64_t> cmp_rows = rows_of(compared_labels, compared_planes, compared.size(), "compared");
  const std::vector<std::int64_t> forward =
      votes(reference, ref_rows, reference_planes, SegmentedPoints(compared, cmp_rows), compared_planes, params, run);
  std::vector<std::int64_t> backward;
  if (params.mutual)
    backward =
        votes(compared, cmp_rows, compared_planes, SegmentedPoints(reference, ref_rows), reference_planes, params, run);
  SegmentPairs out;
  out.compared.assign(reference_planes.size(), -1);
  out.status.assign(reference_planes.size(), PairStatus::kNoPlane);
  for (std::size_t i = 0; i < reference_planes.size(); ++i) {
    if (!std::isfinite(reference_planes.normal[3 * i])) continue;
    const std::int64_t j = forward[i];
    if (j < 0)
      out.status[i] = PairStatus::kNoCandidate;
    else if (params.mutual && backward[std::size_t(j)] != std::int64_t(i))
      out.status[i] = PairStatus::kNotMutual;
    else
      out.compared[i] = j, out.status[i] = PairStatus::kPaired;
  }
  return out;
}

namespace {

/// Spacings a compared point's foot may lie from the nearest reference point of a segment and still be
/// over it: for points spread uniformly at density 1/s^2, a position inside the segment is farther than
/// 2 s from every point with probability exp(-4 pi), 3.5e-6.
constexpr double kReachSpacings = 2.0;

/// Each segment row's points, ascending (points in no row: none).
struct Members {
  Members(const std::vector<std::int64_t>& rows, std::size_t row_count) : first(row_count + 1, 0) {
    for (const std::int64_t r : rows)
      if (r >= 0) ++first[std::size_t(r) + 1];
    for (std::size_t r = 0; r < row_count; ++r) first[r + 1] += first[r];
    point.resize(first.back());
    std::vector<std::size_t> at(first.begin(), first.end() - 1);
    for (std::size_t i = 0; i < rows.size(); ++i)
      if (rows[i] >= 0) point[at[std::size_t(rows[i])]++] = std::uint32_t(i);
  }
  std::span<const std::uint32_t> of(std::size_t row) const {
    return {point.data() + first[row], first[row + 1] - first[row]};
  }
  std::vector<std::size_t> first;
  std::vector<std::uint32_t> point;
};

/// A reference segment's footprint on its own plane: the positions within `reach` of one of its points,
/// measured in the plane. Its points' in-plane coordinates are bucketed in square cells of side `reach`,
/// sorted by cell, so a position is tested against the points of 3 x 3 cells.
class Footprint {
 public:
  void build(PointsView points, std::span<const std::uint32_t> members, const Vec3& centroid, const Vec3& normal,
             double reach) {
    origin_ = centroid;
    u_ = (std::abs(normal.z()) < 0.9 ? Vec3::UnitZ() : Vec3::UnitX()).cross(normal).normalized();
    v_ = normal.cross(u_);
    cells_.clear();
    lo_u_ = lo_v_ = std::numeric_limits<double>::infinity();
    hi_u_ = hi_v_ = -std::numeric_limits<double>::infinity();
    for (const std::uint32_t k : members) {
      const Vec3 d = points[k] - origin_;
      cells_.push_back({0, 0, d.dot(u_), d.dot(v_)});
      lo_u_ = std::min(lo_u_, cells_.back().u), hi_u_ = std::max(hi_u_, cells_.back().u);
      lo_v_ = std::min(lo_v_, cells_.back().v), hi_v_ = std::max(hi_v_, cells_.back().v);
    }
    // At least a billionth of the extent: the cell numbers fit any integer type.
    reach_ = std::max(reach, 1e-9 * std::max(hi_u_ - lo_u_, hi_v_ - lo_v_));
    if (!(std::isfinite(reach_) && reach_ > 0.0)) cells_.clear();
    for (Cell& c : cells_) c.x = cell(c.u, lo_u_), c.y = cell(c.v, lo_v_);
    std::sort(cells_.begin(), cells_.end(), [](const Cell& a, const Cell& b) { return key(a) < key(b); });
  }

  bool contains(const Vec3& p) const {
    const Vec3 d = p - origin_;
    const double a = d.dot(u_), b = d.dot(v_);
    if (cells_.empty() || !(a >= lo_u_ - reach_ && a <= hi_u_ + reach_ && b >= lo_v_ - reach_ && b <= hi_v_ + reach_))
      return false;
    const std::int64_t x = cell(a, lo_u_), y = cell(b, lo_v_);
    for (std::int64_t column = x - 1; column <= x + 1; ++column) {
      auto at =
          std::lower_bound(cells_.begin(), cells_.end(), std::pair(column, y - 1),
                           [](const Cell& c, const std::pair<std::int64_t, std::int64_t>& k) { return key(c) < k; });
      for (; at != cells_.end() && at->x == column && at->y <= y + 1; ++at)
        if ((at->u - a) * (at->u - a) + (at->v - b) * (at->v - b) <= reach_ * reach_) return true;
    }
    return false;
  }

  /// Whether a box may hold a point over the footprint: its shadow on the plane meets the footprint's
  /// rectangle (widened by one more reach, so that rounding never rejects a box contains() would keep).
  bool may_hold(const std::array<double, 3>& lo, const std::array<double, 3>& hi) const {
    const Vec3 centre = 0.5 * (Vec3(lo.data()) + Vec3(hi.data())) - origin_;
    const Vec3 half = 0.5 * (Vec3(hi.data()) - Vec3(lo.data()));
    const double a = centre.dot(u_), b = centre.dot(v_);
    const double ra = half.dot(u_.cwiseAbs()) + 2.0 * reach_, rb = half.dot(v_.cwiseAbs()) + 2.0 * reach_;
    return !cells_.empty() && a + ra >= lo_u_ && a - ra <= hi_u_ && b + rb >= lo_v_ && b - rb <= hi_v_;
  }

 private:
  struct Cell {
    std::int64_t x, y;
    double u, v;
  };
  static std::pair<std::int64_t, std::int64_t> key(const Cell& c) { return {c.x, c.y}; }
  std::int64_t cell(double coordinate, double lo) const { return std::int64_t(std::floor((coordinate - lo) / reach_)); }

  Vec3 origin_, u_, v_;
  double reach_ = 0.0, lo_u_ = 0.0, hi_u_ = 0.0, lo_v_ = 0.0, hi_v_ = 0.0;
  std::vector<Cell> cells_;
};

/// A compared segment's own points, indexed, for a segment paired with several reference segments: each
/// selects the points over its footprint without reading all of them.
struct SegmentIndex {
  std::vector<double> xyz;  // the segment's points, in point order
  std::optional<detail::KdTree> tree;
};

struct MisfitScratch {
  Footprint footprint;
  std::vector<std::uint32_t> found;
};

}  // namespace

PlaneMisfit compared_plane_misfit(PointsView reference, std::span<const std::int64_t> reference_labels,
                                  const PlaneSegments& reference_planes, PointsView compared,
                                  std::span<const std::int64_t> compared_labels, const PlaneSegments& compared_planes,
                                  std::span<const std::int64_t> compared_of_reference, const RunOptions& run) {
  if (compared_of_reference.size() != reference_planes.size())
    throw InvalidArgument("compared_of_reference must have one row per reference segment");
  for (const std::int64_t j : compared_of_reference)
    if (j >= std::int64_t(compared_planes.size()))
      throw InvalidArgument("compared_of_reference names compared row " + std::to_string(j) + " of " +
                            std::to_string(compared_planes.size()));
  for (const PointsView cloud : {reference, compared})
    if (cloud.size() > UINT32_MAX)
      throw InvalidArgument("compared_plane_misfit indexes at most 2^32 - 1 points, got " +
                            std::to_string(cloud.size()));
  const Members ref_members(rows_of(reference_labels, reference_planes, reference.size(), "reference"),
                            reference_planes.size());
  const Members cmp_members(rows_of(compared_labels, compared_planes, compared.size(), "compared"),
                            compared_planes.size());
  // The pairs to measure (both planes defined), and how many reference segments each compared one has.
  std::vector<std::int64_t> pair(reference_planes.size(), -1);
  std::vector<std::size_t> partners(compared_planes.size(), 0);
  for (std::size_t i = 0; i < pair.size(); ++i) {
    const std::int64_t j = compared_of_reference[i];
    if (j < 0 || !std::isfinite(reference_planes.normal[3 * i]) || !std::isfinite(compared_planes.normal[3 * j]))
      continue;
    pair[i] = j, ++partners[std::size_t(j)];
  }
  std::vector<std::size_t> shared;
  for (std::size_t j = 0; j < partners.size(); ++j)
    if (partners[j] > 1) shared.push_back(j);
  std::vector<SegmentIndex> index(compared_planes.size());
  detail::parallel_blocks<int>(
      shared.size(), run,
      [&](std::size_t begin, std::size_t end, int&) {
        for (std::size_t s = begin; s < end; ++s) {
          SegmentIndex& at = index[shared[s]];
          for (const std::uint32_t k : cmp_members.of(shared[s]))
            for (int a = 0; a < 3; ++a) at.xyz.push_back(compared.coord(k, a));
          at.tree.emplace(PointsView(at.xyz.data(), at.xyz.size() / 3));
        }
      },
      1);
  PlaneMisfit out;
  out.mean_residual.assign(reference_planes.size(), std::numeric_limits<double>::quiet_NaN());
  out.points.assign(reference_planes.size(), 0);
  // Each pair alone, its residuals summed in point order: the same bits for any thread count.
  detail::parallel_blocks<MisfitScratch>(
      pair.size(), run,
      [&](std::size_t begin, std::size_t end, MisfitScratch& scratch) {
        for (std::size_t i = begin; i < end; ++i) {
          if (pair[i] < 0) continue;
          const std::size_t j = std::size_t(pair[i]);
          const double area = 12.0 * std::sqrt(reference_planes.eigenvalues[3 * i] *
                                               reference_planes.eigenvalues[3 * i + 1]);  // a rectangle's, exactly
          const double spacing = std::sqrt(area / double(reference_planes.count[i]));
          Footprint& footprint = scratch.footprint;
          footprint.build(reference, ref_members.of(i), Vec3(&reference_planes.centroid[3 * i]),
                          Vec3(&reference_planes.normal[3 * i]), kReachSpacings * spacing);
          const std::span<const std::uint32_t> members = cmp_members.of(j);
          std::vector<std::uint32_t>& over = scratch.found;
          over.clear();
          if (partners[j] == 1) {
            for (std::uint32_t local = 0; local < members.size(); ++local)
              if (footprint.contains(compared[members[local]])) over.push_back(local);
          } else {
            index[j].tree->select([&](const auto& lo, const auto& hi) { return !footprint.may_hold(lo, hi); },
                                  [&](const double* p) { return footprint.contains(Vec3(p[0], p[1], p[2])); }, over);
            std::sort(over.begin(), over.end());
          }
          if (over.empty()) continue;
          const Vec3 c2(&compared_planes.centroid[3 * j]), n2(&compared_planes.normal[3 * j]);
          double sum = 0.0;
          for (const std::uint32_t local : over) sum += (compared[members[local]] - c2).dot(n2);
          out.mean_residual[i] = sum / double(over.size());
          out.points[i] = over.size();
        }
      },
      4);
  return out;
}

}  // namespace m3c2
