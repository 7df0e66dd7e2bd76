// What the reference points' nearest compared points say (include/m3c2/pbm3c2.hpp, docs/pbm3c2.md):
// the overlap rule's votes for their segments, and how far the paired compared plane lies from them.

#include <m3c2/errors.hpp>
#include <m3c2/pbm3c2.hpp>

#include "index/kdtree.hpp"
#include "support/parallel_for.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

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

PlaneMisfit compared_plane_misfit(PointsView reference, std::span<const std::int64_t> reference_labels,
                                  const PlaneSegments& reference_planes, PointsView compared,
                                  std::span<const std::int64_t> compared_labels, const PlaneSegments& compared_planes,
                                  std::span<const std::int64_t> compared_of_reference, double search_radius,
                                  const RunOptions& run) {
  if (!(std::isfinite(search_radius) && search_radius > 0.0))
    throw InvalidArgument("search_radius must be a positive number, got " + std::to_string(search_radius));
  if (compared_of_reference.size() != reference_planes.size())
    throw InvalidArgument("compared_of_reference must have one row per reference segment");
  const std::vector<std::int64_t> ref_rows = rows_of(reference_labels, reference_planes, reference.size(), "reference");
  const std::vector<std::int64_t> cmp_rows = rows_of(compared_labels, compared_planes, compared.size(), "compared");
  const SegmentedPoints to(compared, cmp_rows);
  // Each reference point's compared point (kNone: none), then each compared point once per segment:
  // where the compared epoch covers less than the reference segment, the feet beyond its edge all
  // find the same edge points, and counting them once per foot made the mean's error look far
  // smaller than it is (true planes were refused). Summed in (row, point) order: the same bits for
  // any thread count.
  std::vector<std::uint32_t> nearest(reference.size(), detail::KdTree::kNone);
  detail::parallel_blocks<int>(reference.size(), run, [&](std::size_t begin, std::size_t end, int&) {
    for (std::size_t i = begin; i < end; ++i) {
      if (ref_rows[i] < 0) continue;
      const std::int64_t j = compared_of_reference[std::size_t(ref_rows[i])];
      if (j < 0) continue;
      // The compared point nearest the reference point's foot on the compared plane: chosen by the
      // distance to the plane's own surface, whose noise is symmetric about it, so the residuals'
      // mean is unbiased (the point nearest the reference point itself leans towards it).
      const Vec3 c2(&compared_planes.centroid[3 * std::size_t(j)]), n2(&compared_planes.normal[3 * std::size_t(j)]);
      const Vec3 foot = reference[i] - (reference[i] - c2).dot(n2) * n2;
      const std::uint32_t k = to.tree.nearest(foot, search_radius);
      if (k != detail::KdTree::kNone && to.row[k] == j) nearest[i] = k;
    }
  });
  std::vector<std::pair<std::int64_t, std::uint32_t>> used;
  for (std::size_t i = 0; i < nearest.size(); ++i)
    if (nearest[i] != detail::KdTree::kNone) used.emplace_back(ref_rows[i], nearest[i]);
  std::sort(used.begin(), used.end());
  used.erase(std::unique(used.begin(), used.end()), used.end());
  PlaneMisfit out;
  std::vector<double> sum(reference_planes.size(), 0.0);
  out.points.assign(reference_planes.size(), 0);
  for (const auto& [row, k] : used) {
    const std::size_t j = std::size_t(compared_of_reference[std::size_t(row)]);
    const Vec3 c2(&compared_planes.centroid[3 * j]), n2(&compared_planes.normal[3 * j]);
    sum[std::size_t(row)] += (compared[k] - c2).dot(n2);
    ++out.points[std::size_t(row)];
  }
  out.mean_residual.assign(reference_planes.size(), std::numeric_limits<double>::quiet_NaN());
  for (std::size_t r = 0; r < sum.size(); ++r)
    if (out.points[r] > 0) out.mean_residual[r] = sum[r] / double(out.points[r]);
  return out;
}

}  // namespace m3c2
