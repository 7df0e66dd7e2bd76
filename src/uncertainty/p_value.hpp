#pragma once
// The p-value of the test each level of detection expresses (docs/algorithm.md, "p-values"):
// every LOD of the engine is critical * scale, and "significant" (|d| > LOD) is the test that
// rejects "no change" when the statistic |d| / scale exceeds the critical value of its law. The
// p-value is that law's tail probability at the statistic, decided in the same place as
// `significant`, so that p < 1 - confidence exactly when significant is 1.

#include <m3c2/result.hpp>

#include <cstddef>
#include <cstdint>

namespace m3c2::detail {

/// The law of a LOD's statistic T = |d| / scale under "no change".
struct TestLaw {
  enum class Kind : std::uint8_t {
    kNormal,      ///< two-sided: p = P(|Z| >= T) (eq. (1) with z, the bootstrap, PM, EP's projected LOD)
    kStudent,     ///< two-sided: p = P(|t_dof| >= T) (eq. (1) with Welch's t, eq. (2)'s dof)
    kChiSquared,  ///< p = P(chi2_dof >= T^2) (EP's published LOD, Winiwarter et al. 2021)
  };
  Kind kind = Kind::kNormal;
  double dof = 0.0;  ///< kStudent, kChiSquared
};

/// A LOD and the test it expresses: lod = critical * scale, with critical the law's quantile at
/// the confidence level.
struct LodTest {
  double lod = 0.0;
  double scale = 0.0;
  TestLaw law;
};

/// The law's tail probability at T (above): the unadjusted p-value. T = +inf gives 0; NaN gives NaN.
double tail_probability(double statistic, TestLaw law);

/// Sets r.significant[i] = |r.distance[i]| > test.lod (the LOD's own rule, unchanged) and
/// r.p_value[i] = tail_probability(|d| / scale), moved across alpha = 1 - confidence by at most
/// the rounding that separates the two computations (std::nextafter), so that p < alpha exactly
/// when significant. scale = 0 and d = 0 (0 / 0: a LOD of 0 and no distance): p = 1.
void decide(const LodTest& test, double alpha, std::size_t i, Result& r);

}  // namespace m3c2::detail
