// The change between paired planes and its level of detection (Zahs et al. 2022, 3.5; eq. (1) of
// Lague et al. 2013, 3.3; docs/pbm3c2.md, "Distance and LOD").

#include <m3c2/errors.hpp>
#include <m3c2/pbm3c2.hpp>

#include "uncertainty/confidence.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace m3c2 {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

Vec3 row3(const std::vector<double>& v, std::size_t i) { return {v[3 * i], v[3 * i + 1], v[3 * i + 2]}; }

std::uint32_t as_count(std::uint64_t n) { return std::uint32_t(std::min<std::uint64_t>(n, UINT32_MAX)); }

}  // namespace

PlaneChanges plane_changes(const PlaneSegments& reference, const PlaneSegments& compared,
                           std::span<const std::int64_t> compared_of_reference, const Params& params) {
  if (compared_of_reference.size() != reference.size())
    throw InvalidArgument("compared_of_reference must have one row per reference segment");
  if (params.lod == Lod::kBootstrap) throw InvalidArgument("PB-M3C2's LOD is eq. (1)'s: lod must be z, t or auto");
  if (!(params.confidence > 0.0 && params.confidence < 1.0))
    throw InvalidArgument("confidence must be in (0, 1), got " + std::to_string(params.confidence));
  if (!(std::isfinite(params.registration_error) && params.registration_error >= 0.0))
    throw InvalidArgument("registration_error must be >= 0");
  const double z = detail::z_critical(params.confidence);
  const std::size_t rows = reference.size();
  PlaneChanges out;
  out.distance.assign(rows, kNaN);
  out.lod.assign(rows, kNaN);
  out.significant.assign(rows, 0);
  out.normal_angle.assign(rows, kNaN);
  for (std::size_t i = 0; i < rows; ++i) {
    const std::int64_t j = compared_of_reference[i];
    if (j < 0) continue;
    if (std::size_t(j) >= compared.size()) throw InvalidArgument("compared_of_reference names no compared row");
    const Vec3 c1 = row3(reference.centroid, i), n1 = row3(reference.normal, i);
    const Vec3 c2 = row3(compared.centroid, j), n2 = row3(compared.normal, j);
    const double cosine = n1.dot(n2);
    if (!std::isfinite(cosine) || cosine == 0.0) continue;
    // Along n1 from c1 to the compared plane: the planes' distance where the reference surface is.
    const double t = (c2 - c1).dot(n2) / cosine;
    // Plane 1 is met at its own centroid: its offset's standard error is sigma1 / sqrt(n1). Plane 2
    // is met at L from its centroid: a fitted plane's height there has variance
    // sigma2^2 / n2 (1 + (L.u)^2 / lambda_u + (L.v)^2 / lambda_v) (least squares: the centroid's
    // error and the tilts' along the in-plane axes u, v), projected onto n1.
    const Vec3 along = c1 + t * n1 - c2;
    const Vec3 u = row3(compared.major_axis, j), v = n2.cross(u);
    const double lu = compared.eigenvalues[3 * j], lv = compared.eigenvalues[3 * j + 1];
    const double leverage = 1.0 + along.dot(u) * along.dot(u) / lu + along.dot(v) * along.dot(v) / lv;
    const double n1_points = double(reference.count[i]), n2_points = double(compared.count[j]);
    const double se1 = reference.roughness[i] / std::sqrt(n1_points);
    const double se2 = compared.roughness[j] / std::sqrt(n2_points) * std::sqrt(leverage) / std::abs(cosine);
    out.distance[i] = t;
    out.normal_angle[i] = std::acos(std::min(1.0, std::abs(cosine))) * 180.0 / std::numbers::pi;
    if (!std::isfinite(se1) || !std::isfinite(se2)) continue;  // fewer than 4 points: no spread
    const double critical =
        detail::critical_value(params, z, se1, as_count(reference.count[i]), se2, as_count(compared.count[j]));
    out.lod[i] = detail::lod_parametric(critical, se1, se2, params.registration_error, params.correlated_variance);
    out.significant[i] = std::abs(t) > out.lod[i];
  }
  return out;
}

}  // namespace m3c2
