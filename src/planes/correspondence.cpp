// Which compared segment is the same surface as each reference segment (Zahs et al. 2022, 3.4):
// the geometric rule, and the candidates a classifier scores (m3c2kit.pbm3c2, docs/pbm3c2.md).

#include <m3c2/errors.hpp>
#include <m3c2/pbm3c2.hpp>

#include "index/kdtree.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>

namespace m3c2 {
namespace {

Vec3 row3(const std::vector<double>& v, std::size_t i) { return {v[3 * i], v[3 * i + 1], v[3 * i + 2]}; }

/// The most candidate pairs segment_candidates() lists (16 B each, 40 B with their features): a
/// search radius wide enough to pair every segment with every other is refused before it fills memory.
constexpr std::size_t kMaxCandidates = 20'000'000;

bool has_plane(const PlaneSegments& s, std::size_t i) { return std::isfinite(s.normal[3 * i]); }

void check_radius(double radius) {
  if (!(std::isfinite(radius) && radius > 0.0))
    throw InvalidArgument("search_radius must be a positive number, got " + std::to_string(radius));
}

/// The centroids of the segments that have a plane, indexed; `rows` maps back to segment rows.
struct CentroidIndex {
  explicit CentroidIndex(const PlaneSegments& s) {
    for (std::size_t i = 0; i < s.size(); ++i)
      if (has_plane(s, i)) {
        rows.push_back(i);
        for (int a = 0; a < 3; ++a) xyz.push_back(s.centroid[3 * i + a]);
      }
    tree.emplace(PointsView(xyz.data(), rows.size()));
  }
  /// The rows within `radius` of `centre`, ascending.
  void within(const Vec3& centre, double radius, std::vector<std::size_t>& out) const {
    found.clear();
    tree->ball(centre, radius, found);
    out.clear();
    for (const std::uint32_t k : found) out.push_back(rows[k]);
    std::sort(out.begin(), out.end());
  }
  std::vector<std::size_t> rows;
  std::vector<double> xyz;
  std::optional<detail::KdTree> tree;
  mutable std::vector<std::uint32_t> found;
};

/// The row of `to` nearest segment `i` of `from` within the gates, or -1. Balls growing by 4 from
/// search_radius / 64: the nearest row passing the angle gate within a ball is the nearest of all
/// (every row outside is farther than the ball's radius), so a wide search radius costs no more
/// than the distance to the pair.
std::int64_t nearest(const PlaneSegments& from, std::size_t i, const PlaneSegments& to, const CentroidIndex& index,
                     const CorrespondenceParams& params, double min_cosine, std::vector<std::size_t>& scratch) {
  const Vec3 c = row3(from.centroid, i), n = row3(from.normal, i);
  for (double radius = params.search_radius / 64.0;; radius = std::min(4.0 * radius, params.search_radius)) {
    index.within(c, radius, scratch);
    std::int64_t best = -1;
    double best2 = std::numeric_limits<double>::infinity();
    for (const std::size_t j : scratch) {  // ascending: a tie keeps the lower row
      if (std::abs(n.dot(row3(to.normal, j))) < min_cosine) continue;
      const double d2 = (row3(to.centroid, j) - c).squaredNorm();
      if (d2 < best2) best2 = d2, best = std::int64_t(j);
    }
    if (best >= 0 || radius >= params.search_radius) return best;
  }
}

}  // namespace

SegmentPairs nearest_segments(const PlaneSegments& reference, const PlaneSegments& compared,
                              const CorrespondenceParams& params) {
  check_radius(params.search_radius);
  if (!(params.max_angle_degrees > 0.0 && params.max_angle_degrees <= 90.0))
    throw InvalidArgument("max_angle_degrees must be in (0, 90], got " + std::to_string(params.max_angle_degrees));
  const double min_cosine = std::cos(params.max_angle_degrees * std::numbers::pi / 180.0);
  const CentroidIndex compared_index(compared), reference_index(reference);
  std::vector<std::size_t> scratch;
  SegmentPairs out;
  out.compared.assign(reference.size(), -1);
  out.status.assign(reference.size(), PairStatus::kNoPlane);
  for (std::size_t i = 0; i < reference.size(); ++i) {
    if (!has_plane(reference, i)) continue;
    const std::int64_t j = nearest(reference, i, compared, compared_index, params, min_cosine, scratch);
    if (j < 0) {
      out.status[i] = PairStatus::kNoCandidate;
    } else if (params.mutual && nearest(compared, std::size_t(j), reference, reference_index, params, min_cosine,
                                        scratch) != std::int64_t(i)) {
      out.status[i] = PairStatus::kNotMutual;
    } else {
      out.compared[i] = j, out.status[i] = PairStatus::kPaired;
    }
  }
  return out;
}

SegmentCandidates segment_candidates(const PlaneSegments& reference, const PlaneSegments& compared,
                                     double search_radius) {
  check_radius(search_radius);
  const CentroidIndex compared_index(compared);
  std::vector<std::size_t> within;
  SegmentCandidates out;
  for (std::size_t i = 0; i < reference.size(); ++i) {
    if (!has_plane(reference, i)) continue;
    compared_index.within(row3(reference.centroid, i), search_radius, within);
    for (const std::size_t j : within)
      out.reference.push_back(std::int64_t(i)), out.compared.push_back(std::int64_t(j));
  }
  return out;
}

PairFeatures pair_features(const PlaneSegments& reference, const PlaneSegments& compared,
                           std::span<const std::int64_t> reference_rows, std::span<const std::int64_t> compared_rows) {
  if (reference_rows.size() != compared_rows.size())
    throw InvalidArgument("pair_features needs as many compared rows as reference rows");
  PairFeatures out;
  for (std::size_t k = 0; k < reference_rows.size(); ++k) {
    const std::int64_t i = reference_rows[k], j = compared_rows[k];
    if (i < 0 || std::size_t(i) >= reference.size() || j < 0 || std::size_t(j) >= compared.size())
      throw InvalidArgument("pair " + std::to_string(k) + " names a segment row out of range");
    const Vec3 n1 = row3(reference.normal, i), n2 = row3(compared.normal, j);
    out.centroid_distance.push_back((row3(compared.centroid, j) - row3(reference.centroid, i)).norm());
    // Unoriented: a plane seen from the other side is the same plane.
    out.normal_angle.push_back(std::acos(std::min(1.0, std::abs(n1.dot(n2)))));
    out.roughness_difference.push_back(std::abs(reference.roughness[i] - compared.roughness[j]));
  }
  return out;
}

}  // namespace m3c2
