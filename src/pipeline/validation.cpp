#include "pipeline/validation.hpp"

#include <m3c2/errors.hpp>
#include <m3c2/m3c2.hpp>

#include "support/number_text.hpp"

#include <cmath>
#include <string>

namespace m3c2::detail {
namespace {

[[noreturn]] void fail(std::string_view name, std::string_view rule, double value) {
  throw InvalidArgument(std::string(name) + " must be " + std::string(rule) + ", got " + number_text(value, 17));
}

}  // namespace

void require_positive(std::string_view name, double value) {
  if (!(value > 0.0) || !std::isfinite(value)) fail(name, "finite and > 0", value);  // rejects NaN too
}

void require_finite_points(std::string_view name, PointsView points) {
  std::size_t bad = 0;
  for (std::size_t i = 0; i < 3 * points.size(); ++i) bad += !std::isfinite(points.data()[i]);
  if (bad)
    throw InvalidArgument(std::string(name) + " has " + std::to_string(bad) + " non-finite coordinates (NaN or Inf)");
}

void require_cell_count(std::string_view name, double cell, PointsView points) {
  if (points.empty()) return;
  Vec3 lo = points[0], hi = points[0];
  for (std::size_t i = 1; i < points.size(); ++i) lo = lo.cwiseMin(points[i]), hi = hi.cwiseMax(points[i]);
  const double cells = (hi - lo).maxCoeff() / cell;
  if (!(cells <= kMaxCellsPerAxis))
    throw InvalidArgument(std::string(name) + " " + number_text(cell, 17) + " is too small for the points' extent " +
                          number_text((hi - lo).maxCoeff(), 17) + " (more than 2^40 cells along an axis)");
}

void validate_normal_params(const Params& p) {
  if (p.normal_diameters.empty()) throw InvalidArgument("normal_diameters (D) must not be empty");
  for (const double d : p.normal_diameters) require_positive("normal diameter D", d);
  if (p.min_points_normal < 3) fail("min_points_normal", ">= 3 (a plane needs 3 points)", p.min_points_normal);
  if (p.normal_subsample_spacing < 0.0 || !std::isfinite(p.normal_subsample_spacing))
    fail("normal_subsample_spacing", "finite and >= 0", p.normal_subsample_spacing);
  validate_orientation(p.orientation);
}

void validate_orientation(const Orientation& o) {
  for (const double c : o.direction)
    if (!std::isfinite(c)) fail("orientation direction", "finite", c);
  const auto& d = o.direction;
  if (d[0] == 0.0 && d[1] == 0.0 && d[2] == 0.0)
    throw InvalidArgument("orientation direction must not be the zero vector");
  if (o.points.size() % 3 != 0) throw InvalidArgument("orientation points must hold 3 coordinates per point");
  for (const double c : o.points)
    if (!std::isfinite(c)) fail("orientation point coordinate", "finite", c);
  if (o.away && o.points.empty()) throw InvalidArgument("orientation away from a point needs orientation points");
}

void validate_params(const Params& p) {
  const bool imposed = p.normal_source == NormalSource::kVertical || p.normal_source == NormalSource::kCorePoints;
  if (!imposed || !p.normal_diameters.empty()) validate_normal_params(p);
  validate_orientation(p.orientation);
  require_positive("projection diameter d", p.projection_diameter);
  require_positive("max_depth", p.max_depth);
  if (p.depth_search == DepthSearch::kTwoPass) {
    require_positive("first_pass_depth", p.first_pass_depth);
    if (p.first_pass_depth > p.max_depth)
      fail("first_pass_depth", "<= max_depth (" + number_text(p.max_depth, 17) + ")", p.first_pass_depth);
  }
  if (!(p.registration_error >= 0.0) || !std::isfinite(p.registration_error))
    fail("registration_error", "finite and >= 0", p.registration_error);
  if (!(p.confidence > 0.0 && p.confidence < 1.0)) fail("confidence", "in (0, 1)", p.confidence);
  if (!(p.correlated_variance >= 0.0) || !std::isfinite(p.correlated_variance))
    fail("correlated_variance", "finite and >= 0", p.correlated_variance);
  if (p.min_points < 1) fail("min_points", ">= 1", p.min_points);
  if (p.lod == Lod::kBootstrap && p.bootstrap_samples < 2)
    fail("bootstrap_samples", ">= 2 with the bootstrap LOD", p.bootstrap_samples);
  if (p.bootstrap_samples > kMaxBootstrapSamples)
    fail("bootstrap_samples", "at most " + std::to_string(kMaxBootstrapSamples), p.bootstrap_samples);
}

}  // namespace m3c2::detail
