#include "uncertainty/p_value.hpp"

#include <boost/math/distributions/chi_squared.hpp>
#include <boost/math/distributions/normal.hpp>
#include <boost/math/distributions/students_t.hpp>

#include <algorithm>
#include <cmath>

namespace m3c2::detail {

double tail_probability(double statistic, TestLaw law) {
  if (std::isnan(statistic)) return statistic;
  if (std::isinf(statistic)) return 0.0;
  using boost::math::cdf;
  using boost::math::complement;
  switch (law.kind) {
    case TestLaw::Kind::kNormal: return 2.0 * cdf(complement(boost::math::normal(), statistic));
    case TestLaw::Kind::kStudent: return 2.0 * cdf(complement(boost::math::students_t(law.dof), statistic));
    case TestLaw::Kind::kChiSquared: return cdf(complement(boost::math::chi_squared(law.dof), statistic * statistic));
  }
  return std::nan("");
}

void decide(const LodTest& test, double alpha, std::size_t i, Result& r) {
  const double d = std::abs(r.distance[i]);
  const bool significant = d > test.lod;
  r.significant[i] = significant;
  double p = tail_probability(d / test.scale, test.law);
  if (std::isnan(p)) p = 1.0;  // 0 / 0: the LOD is 0 and so is the distance, nothing was detected
  // `significant` compares |d| with critical * scale, p compares |d| / scale with the law: both are
  // the same test, but each rounds on its own, so where |d| lies within a few ulps of the LOD the
  // two may fall on either side of alpha. The LOD's rule is the contract (it is the paper's and
  // decides every other output): p takes the nearest value on its side (docs/algorithm.md, "p-values").
  if (significant && !(p < alpha)) p = std::nextafter(alpha, 0.0);
  if (!significant && p < alpha) p = alpha;
  r.p_value[i] = std::min(std::max(p, 0.0), 1.0);
}

}  // namespace m3c2::detail
