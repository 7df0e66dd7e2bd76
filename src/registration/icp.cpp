// Point-to-plane ICP (Chen & Medioni 1992; the iteration of Besl & McKay 1992): pair, reject,
// solve the linearised least squares for a small rotation and a shift, repeat. The covariance is
// sigma^2 (J^T J)^-1 at the estimate. docs/registration.md derives each step.

#include <m3c2/errors.hpp>
#include <m3c2/registration.hpp>

#include "pipeline/validation.hpp"
#include "registration/observability.hpp"
#include "registration/pairing.hpp"
#include "registration/rotation.hpp"
#include "support/number_text.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace m3c2 {
namespace {

using detail::Matrix6d;
using detail::number_text;
using detail::Vector6d;

// 1.4826 MAD is the standard deviation of normal residuals (the MAD of N(0, 1) is 0.6745 = 1 / 1.4826).
constexpr double kMadToSigma = 1.4826;

void validate(const RegistrationParams& p) {
  detail::require_positive("normal_diameter", p.normal_diameter);
  detail::require_positive("max_distance", p.max_distance);
  detail::require_positive("tolerance", p.tolerance);
  if (!(std::isfinite(p.reject) && p.reject >= 0.0))
    throw InvalidArgument("reject must be finite and >= 0, got " + number_text(p.reject, 6));
  if (p.max_iterations < 1) throw InvalidArgument("max_iterations must be >= 1");
  if (p.min_pairs < 7) throw InvalidArgument("min_pairs must be >= 7 (six parameters and a residual variance)");
  if (p.max_points < p.min_pairs) throw InvalidArgument("max_points must be >= min_pairs");
}

/// The residuals kept: within `reject` robust standard deviations of their median ([-inf, inf]
/// without rejection or spread). nth_element on a copy in source order: deterministic.
std::pair<double, double> accepted_range(const std::vector<double>& residual, double reject) {
  constexpr double inf = std::numeric_limits<double>::infinity();
  std::vector<double> r;
  r.reserve(residual.size());
  for (const double v : residual)
    if (std::isfinite(v)) r.push_back(v);
  if (r.empty() || reject == 0.0) return {-inf, inf};
  const auto mid = r.begin() + std::ptrdiff_t(r.size() / 2);
  std::nth_element(r.begin(), mid, r.end());
  const double median = *mid;
  for (double& v : r) v = std::abs(v - median);
  std::nth_element(r.begin(), mid, r.end());
  const double sigma = kMadToSigma * *mid;
  if (!(sigma > 0.0)) return {-inf, inf};
  return {median - reject * sigma, median + reject * sigma};
}

struct Step {
  detail::NormalEquations equations;
  double low = 0.0, high = 0.0;
};

Step paired(const detail::Targets& targets, const detail::Sources& sources, const detail::Pose& pose,
            const RegistrationParams& p, double radius, detail::Pairing& pairing, const RunOptions& run) {
  detail::pair_sources(targets, sources, pose, p.max_distance, pairing, run);
  Step s;
  std::tie(s.low, s.high) = accepted_range(pairing.residual, p.reject);
  s.equations = detail::normal_equations(targets, sources, pose, pairing, s.low, s.high, run);
  if (s.equations.pairs < p.min_pairs)
    throw InvalidArgument("only " + std::to_string(s.equations.pairs) + " of " + std::to_string(sources.count) +
                          " compared points have a reference point within max_distance " +
                          number_text(p.max_distance, 6) + " and a residual kept (at least " +
                          std::to_string(p.min_pairs) +
                          " needed): the clouds are not roughly aligned, the max distance is too small, or the "
                          "stable areas hold too few points");
  detail::require_observable(s.equations.jtj, radius);
  return s;
}

/// (J^T J)^-1 through the rotations scaled by `radius` (both blocks lengths: better conditioned).
Matrix6d inverse(const Matrix6d& jtj, double radius) {
  Vector6d scale;
  scale << 1.0 / radius, 1.0 / radius, 1.0 / radius, 1.0, 1.0, 1.0;
  const Matrix6d scaled = scale.asDiagonal() * jtj * scale.asDiagonal();
  const Matrix6d inv = scaled.ldlt().solve(Matrix6d::Identity());
  return scale.asDiagonal() * inv * scale.asDiagonal();
}

}  // namespace

Registration register_clouds(PointsView reference, PointsView compared, const RegistrationParams& p,
                             const RunOptions& run) {
  validate(p);
  if (reference.empty()) throw InvalidArgument("the reference cloud is empty");
  if (compared.empty()) throw InvalidArgument("the compared cloud is empty");
  detail::require_finite_points("the reference cloud", reference);
  detail::require_finite_points("the compared cloud", compared);

  detail::Sources sources{compared, 1, compared.size()};
  sources.stride = (compared.size() + p.max_points - 1) / p.max_points;
  sources.count = (compared.size() + sources.stride - 1) / sources.stride;
  // The centre: the sources' mean, so that the rotation and the shift are nearly uncorrelated
  // and J's rows are small numbers (UTM coordinates are about 1e6). A serial sum: fixed order.
  Vec3 centre = Vec3::Zero();
  for (std::size_t j = 0; j < sources.count; ++j) centre += sources[j];
  centre /= double(sources.count);
  double sum_squares = 0.0, farthest = 0.0;
  for (std::size_t j = 0; j < sources.count; ++j) {
    const double d2 = (sources[j] - centre).squaredNorm();
    sum_squares += d2, farthest = std::max(farthest, d2);
  }
  const double radius = std::sqrt(sum_squares / double(sources.count));
  farthest = std::sqrt(farthest);
  if (!(radius > 0.0)) throw InvalidArgument("the compared points are all at one position: no motion to estimate");

  const detail::Targets targets(reference, p.normal_diameter, run);
  if (targets.size() < p.min_pairs)
    throw InvalidArgument("only " + std::to_string(targets.size()) + " reference points have a plane at D = " +
                          number_text(p.normal_diameter, 6) + " (at least " + std::to_string(p.min_pairs) +
                          " needed): the stable areas hold too few points, or D is too small for their spacing");

  detail::Pose pose;
  pose.centre = centre;
  detail::Pairing pairing;
  Registration out;
  out.candidates = sources.count;
  for (std::uint32_t it = 1; it <= p.max_iterations; ++it) {
    const Step s = paired(targets, sources, pose, p, radius, pairing, run);
    const Vector6d delta = -(inverse(s.equations.jtj, radius) * s.equations.jtr);
    const Vec3 w = delta.head<3>(), shift = delta.tail<3>();
    const Eigen::Matrix3d turn = detail::rotation_from_vector(w);
    // A source moves by (turn - I)(q' - centre) + shift, at most |w| |q' - centre| + |shift|.
    const double moved = w.norm() * (farthest + pose.translation.norm()) + shift.norm();
    pose.rotation = turn * pose.rotation;
    pose.translation = turn * pose.translation + shift;
    out.iterations = it;
    if (moved <= p.tolerance * radius) {
      out.converged = true;
      break;
    }
  }
  // The covariance and the residuals of the estimate: its own pairs, J at the estimate.
  const Step last = paired(targets, sources, pose, p, radius, pairing, run);
  const auto& eq = last.equations;
  const double variance = eq.sum_squares / double(eq.pairs - 6);
  const Matrix6d covariance = variance * inverse(eq.jtj, radius);
  out.registration_error = std::sqrt(variance);
  out.rms = std::sqrt(eq.sum_squares / double(eq.pairs));
  out.pairs = eq.pairs;
  for (int a = 0; a < 6; ++a)
    for (int b = 0; b < 6; ++b) out.covariance[6 * a + b] = 0.5 * (covariance(a, b) + covariance(b, a));
  const Vec3 offset = centre + pose.translation - pose.rotation * centre;
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) out.matrix[4 * a + b] = pose.rotation(a, b);
    out.matrix[4 * a + 3] = offset(a);
    out.centre[a] = centre(a);
  }
  out.matrix[15] = 1.0;
  return out;
}

}  // namespace m3c2
