#include "uncertainty/confidence.hpp"

#include <boost/math/distributions/normal.hpp>
#include <boost/math/distributions/students_t.hpp>

#include <algorithm>
#include <cmath>

namespace m3c2::detail {

double z_critical(double confidence) {
  const boost::math::normal standard;
  return boost::math::quantile(boost::math::complement(standard, 0.5 * (1.0 - confidence)));
}

double t_critical(double confidence, double dof) {
  const boost::math::students_t student(dof);
  return boost::math::quantile(boost::math::complement(student, 0.5 * (1.0 - confidence)));
}

double welch_dof(double se1, double n1, double se2, double n2, double known_variance) {
  const double a = se1 * se1, b = se2 * se2, total = a + b + known_variance;
  return total * total / (a * a / (n1 - 1.0) + b * b / (n2 - 1.0));
}

TestLaw critical_law(const Params& params, double se1, std::uint32_t n1, double se2, std::uint32_t n2) {
  switch (params.lod) {
    case Lod::kZ:
    case Lod::kBootstrap: return {};
    case Lod::kAuto:
      if (n1 >= 30 && n2 >= 30) return {};
      if (params.statistic == Statistic::kMedian && params.median_lod == MedianLod::kMaritzJarrett) return {};
      break;
    case Lod::kT: break;
  }
  double dof = welch_dof(se1, n1, se2, n2, params.correlated_variance);
  // Both spreads zero (an exactly planar surface) leave eq. (2) as 0/0; Welch's conservative
  // lower bound min(n1, n2) - 1 is used instead.
  if (!std::isfinite(dof) || dof <= 0.0) dof = double(std::min(n1, n2)) - 1.0;
  return {TestLaw::Kind::kStudent, dof};
}

double critical_value(const Params& params, double z, double se1, std::uint32_t n1, double se2, std::uint32_t n2) {
  const TestLaw law = critical_law(params, se1, n1, se2, n2);
  return law.kind == TestLaw::Kind::kNormal ? z : t_critical(params.confidence, law.dof);
}

LodTest parametric_test(const Params& params, double z, double se1, std::uint32_t n1, double se2, std::uint32_t n2) {
  LodTest test;
  test.law = critical_law(params, se1, n1, se2, n2);
  const double critical = test.law.kind == TestLaw::Kind::kNormal ? z : t_critical(params.confidence, test.law.dof);
  test.lod = lod_parametric(critical, se1, se2, params.registration_error, params.correlated_variance);
  test.scale = lod_scale(se1, se2, params.registration_error, params.correlated_variance);
  return test;
}

LodTest bootstrap_test(const Params& params, double z, double bootstrap_sigma) {
  // The bootstrap's sigma is of the uncorrelated part; the correlated one adds independently.
  LodTest test;
  test.scale = std::sqrt(bootstrap_sigma * bootstrap_sigma + params.correlated_variance) + params.registration_error;
  test.lod = z * test.scale;
  return test;
}

double lod_parametric(double critical, double se1, double se2, double registration_error, double correlated_variance) {
  return critical * lod_scale(se1, se2, registration_error, correlated_variance);
}

double lod_scale(double se1, double se2, double registration_error, double correlated_variance) {
  return std::sqrt(se1 * se1 + se2 * se2 + correlated_variance) + registration_error;
}

}  // namespace m3c2::detail
