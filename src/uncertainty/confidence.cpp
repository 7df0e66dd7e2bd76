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

double welch_dof(double se1, std::uint32_t n1, double se2, std::uint32_t n2) {
  const double a = se1 * se1, b = se2 * se2;
  return (a + b) * (a + b) / (a * a / (double(n1) - 1.0) + b * b / (double(n2) - 1.0));
}

double critical_value(const Params& params, double z, double se1, std::uint32_t n1, double se2, std::uint32_t n2) {
  switch (params.lod) {
    case Lod::kZ:
    case Lod::kBootstrap: return z;
    case Lod::kAuto:
      if (n1 >= 30 && n2 >= 30) return z;
      if (params.statistic == Statistic::kMedian && params.median_lod == MedianLod::kMaritzJarrett) return z;
      break;
    case Lod::kT: break;
  }
  double dof = welch_dof(se1, n1, se2, n2);
  // Both spreads zero (an exactly planar surface) leave eq. (2) as 0/0; Welch's conservative
  // lower bound min(n1, n2) - 1 is used instead.
  if (!std::isfinite(dof) || dof <= 0.0) dof = double(std::min(n1, n2)) - 1.0;
  return t_critical(params.confidence, dof);
}

double lod_parametric(double critical, double se1, double se2, double registration_error) {
  return critical * (std::sqrt(se1 * se1 + se2 * se2) + registration_error);
}

}  // namespace m3c2::detail
