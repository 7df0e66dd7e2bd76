// Region growing on normals (Rabbani et al. 2006), the planar segmentation PB-M3C2 starts from
// (Zahs et al. 2022, 3.2; docs/pbm3c2.md, "Segmentation").

#include <m3c2/errors.hpp>
#include <m3c2/m3c2.hpp>
#include <m3c2/pbm3c2.hpp>

#include "index/kdtree.hpp"
#include "pipeline/plane_fit.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>

namespace m3c2 {
namespace {

void check(const PlaneSegmentationParams& p) {
  if (!(std::isfinite(p.normal_diameter) && p.normal_diameter > 0.0))
    throw InvalidArgument("normal_diameter must be a positive number, got " + std::to_string(p.normal_diameter));
  if (!(std::isfinite(p.growth_diameter) && p.growth_diameter >= 0.0))
    throw InvalidArgument("growth_diameter must be >= 0 (0: normal_diameter), got " +
                          std::to_string(p.growth_diameter));
  if (!(p.max_angle_degrees > 0.0 && p.max_angle_degrees <= 90.0))
    throw InvalidArgument("max_angle_degrees must be in (0, 90], got " + std::to_string(p.max_angle_degrees));
  if (!(std::isfinite(p.max_plane_distance) && p.max_plane_distance >= 0.0))
    throw InvalidArgument("max_plane_distance must be >= 0 (0: normal_diameter / 4), got " +
                          std::to_string(p.max_plane_distance));
  if (p.min_points < 1) throw InvalidArgument("min_points must be >= 1");
  if (p.min_normal_points < 3) throw InvalidArgument("min_normal_points must be >= 3 (a plane)");
}

/// The plane a growing segment is tested against: sums of its points' offsets from its seed
/// (small numbers: no cancellation at projected coordinates), refitted when the segment doubles.
class GrowingPlane {
 public:
  GrowingPlane(const Vec3& seed, const Vec3& normal) : seed_(seed), centre_(seed), normal_(normal) {}

  void add(const Vec3& p) {
    const Vec3 v = p - seed_;
    sum_ += v, products_ += v * v.transpose(), ++count_;
    if (count_ >= refit_at_) refit();
  }
  /// Distance of p from the plane and |cos| of the angle between `normal` and the plane's.
  double distance(const Vec3& p) const { return std::abs((p - centre_).dot(normal_)); }
  double cosine(const Vec3& normal) const { return std::abs(normal.dot(normal_)); }

 private:
  void refit() {
    refit_at_ *= 2;
    const Vec3 mean = sum_ / double(count_);
    const Eigen::Matrix3d comoment = products_ - double(count_) * mean * mean.transpose();
    const detail::PlaneFit fit = detail::fit_plane(comoment);
    if (fit.degenerate) return;  // a line of points so far: keep the seed's plane
    centre_ = seed_ + mean, normal_ = fit.normal;
  }

  Vec3 seed_, centre_, normal_;
  Vec3 sum_ = Vec3::Zero();
  Eigen::Matrix3d products_ = Eigen::Matrix3d::Zero();
  std::uint64_t count_ = 1, refit_at_ = 8;  // the seed: offset 0
};

}  // namespace

PlaneSegmentation segment_planes(PointsView points, const PlaneSegmentationParams& params, const RunOptions& run) {
  check(params);
  const std::size_t n = points.size();
  if (n > UINT32_MAX) throw InvalidArgument("segment_planes indexes at most 2^32 - 1 points, got " + std::to_string(n));
  Params normal_params;
  normal_params.normal_diameters = {params.normal_diameter};
  normal_params.min_points_normal = params.min_normal_points;
  // Checks the coordinates (finite, within the index's range) and reports progress.
  const NormalsResult normals = compute_normals(points, points, normal_params, run);

  PlaneSegmentation out;
  out.labels.assign(n, -1);
  out.status.assign(n, SegmentStatus::kNoNormal);
  std::vector<std::size_t> seeds;
  for (std::size_t i = 0; i < n; ++i)
    if (normals.status[i] == PointStatus::kOk) seeds.push_back(i);
  // Flattest first (Rabbani et al. 2006): a segment starts inside a plane, not on its edge.
  std::stable_sort(seeds.begin(), seeds.end(),
                   [&](std::size_t a, std::size_t b) { return normals.roughness[a] < normals.roughness[b]; });

  const double radius = 0.5 * (params.growth_diameter > 0.0 ? params.growth_diameter : params.normal_diameter);
  // 0: D / 4. A cut at a few times the points' noise (three times the median sigma(D) was tried)
  // trims a segment's noise tails against its growing plane: its sigma comes out low and its plane
  // fitted to a cut sample, and the LOD covered 88 % of known moves instead of 95 % (docs/validation.md,
  // "PB-M3C2"). A segment too wide for a plane is caught by its misfit (docs/pbm3c2.md).
  const double max_distance = params.max_plane_distance > 0.0 ? params.max_plane_distance : params.normal_diameter / 4;
  const double min_cosine = std::cos(params.max_angle_degrees * std::numbers::pi / 180.0);
  const auto normal_of = [&](std::size_t i) {
    return Vec3(normals.normal[3 * i], normals.normal[3 * i + 1], normals.normal[3 * i + 2]);
  };
  const detail::KdTree tree(points);
  std::vector<std::uint8_t> taken(n, 0);
  std::vector<std::uint32_t> region, found;
  std::int64_t next_label = 0;
  for (const std::size_t seed : seeds) {
    if (taken[seed]) continue;
    GrowingPlane plane(points[seed], normal_of(seed));
    region.assign(1, std::uint32_t(seed));
    taken[seed] = 1;
    for (std::size_t k = 0; k < region.size(); ++k) {
      found.clear();
      tree.ball(points[region[k]], radius, found);
      for (const std::uint32_t j : found) {
        if (taken[j] || normals.status[j] != PointStatus::kOk) continue;
        const Vec3 p = points[j];
        if (plane.cosine(normal_of(j)) < min_cosine || plane.distance(p) > max_distance) continue;
        taken[j] = 1;
        region.push_back(j);
        plane.add(p);
      }
    }
    const bool kept = region.size() >= params.min_points;
    for (const std::uint32_t j : region) {
      out.labels[j] = kept ? next_label : -1;
      out.status[j] = kept ? SegmentStatus::kSegmented : SegmentStatus::kSmallSegment;
    }
    next_label += kept;
  }
  out.segments = std::uint64_t(next_label);
  return out;
}

}  // namespace m3c2
