// Level of detection (section 3.3, eq. (1) and the Welch DF, Appendix B bootstrap) on cylinders
// whose contents are chosen by hand, so i1, i2, sigma1, sigma2 and the LOD are known exactly.
//
// Layout: the core point is the origin, normals are imposed vertical (NormalSource::kVertical),
// so the position of a point along the normal is its z. Cylinder points sit on a circle of
// radius 0.05 around the axis (inside d / 2 = 0.1), not collinear.

#include "test_support.hpp"

#include <algorithm>
#include <numeric>

namespace m3c2::test {
namespace {

constexpr double kZ95 = 1.959963984540054;   // Phi^-1(0.975)
constexpr double kZ99 = 2.5758293035489004;  // Phi^-1(0.995)
// Two-tailed Student t quantiles (mpmath 1.3, 30 digits: betainc-based inverse CDF).
constexpr double kT975df10 = 2.2281388519862742;
constexpr double kT995df20 = 2.8453397097861081;
// t_{0.975} at the non-integer DF of the (n1 = 5, var 2.5; n2 = 8, var 40/7) pair below.
constexpr double kT975df10_89098 = 2.2036761398982298;

Cloud axis_cluster(const std::vector<double>& z, const Vec3& centre = Vec3::Zero()) {
  Cloud c;
  for (std::size_t k = 0; k < z.size(); ++k) {
    const double a = 0.7 * static_cast<double>(k);
    c.add(centre + Vec3(0.05 * std::cos(a), 0.05 * std::sin(a), z[k]));
  }
  return c;
}

Params vertical_params() {
  Params p;
  p.normal_diameters = {1.0};
  p.normal_source = NormalSource::kVertical;
  p.projection_diameter = 0.2;
  p.max_depth = 500.0;
  return p;
}

Result run_one(const std::vector<double>& z1, const std::vector<double>& z2, const Params& p,
               const RunOptions& run = {}) {
  const Cloud ref = axis_cluster(z1), cmp = axis_cluster(z2);
  Cloud core;
  core.add(0, 0, 0);
  return compute(ref.view(), cmp.view(), core.view(), p, run);
}

double sample_var(const std::vector<double>& z) {
  const double m = std::accumulate(z.begin(), z.end(), 0.0) / static_cast<double>(z.size());
  double s = 0;
  for (double v : z) s += (v - m) * (v - m);
  return s / static_cast<double>(z.size() - 1);
}

// Cloud 1: mean 0, sample variance 10/4 = 2.5. Cloud 2: mean 10, sample variance 40/7.
const std::vector<double> kZ1 = {-2, -1, 0, 1, 2};
const std::vector<double> kZ2 = {7, 9, 11, 13, 7, 9, 11, 13};

TEST(Lod, MeanModeGivesExactPositionsSpreadsAndCounts) {
  const Result r = run_one(kZ1, kZ2, vertical_params());
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r.status[0], PointStatus::kOk);
  EXPECT_EQ(r.n1[0], 5u);
  EXPECT_EQ(r.n2[0], 8u);
  // Rounding only: sums of small integers, divisions and sqrt (a few ulp).
  EXPECT_NEAR(r.i1[0], 0.0, 1e-14);
  EXPECT_NEAR(r.i2[0], 10.0, 1e-13);
  EXPECT_NEAR(r.distance[0], 10.0, 1e-13);
  EXPECT_NEAR(r.sigma1[0], std::sqrt(2.5), 1e-13);
  EXPECT_NEAR(r.sigma2[0], std::sqrt(40.0 / 7.0), 1e-13);
  EXPECT_NEAR(r.normal[2], 1.0, 1e-15);
}

TEST(Lod, Eq1At95PercentUsesZ1_959963984540054) {
  const Result r = run_one(kZ1, kZ2, vertical_params());
  const double expected = kZ95 * std::sqrt(2.5 / 5 + (40.0 / 7.0) / 8);
  EXPECT_NEAR(r.lod[0], expected, 1e-12 * expected);
  EXPECT_EQ(r.significant[0], 1);  // 10 > 2.1
}

TEST(Lod, Eq1At99PercentUsesZ2_5758293035489) {
  Params p = vertical_params();
  p.confidence = 0.99;
  const Result r = run_one(kZ1, kZ2, p);
  const double expected = kZ99 * std::sqrt(2.5 / 5 + (40.0 / 7.0) / 8);
  EXPECT_NEAR(r.lod[0], expected, 1e-12 * expected);
}

TEST(Lod, RegistrationErrorIsAddedInsideTheParentheses) {
  Params p = vertical_params();
  p.registration_error = 0.3;
  const Result r = run_one(kZ1, kZ2, p);
  const double expected = kZ95 * (std::sqrt(2.5 / 5 + (40.0 / 7.0) / 8) + 0.3);
  EXPECT_NEAR(r.lod[0], expected, 1e-12 * expected);
}

TEST(Lod, PopulationVarianceUsesNDenominator) {
  Params p = vertical_params();
  p.variance = Variance::kPopulation;
  const Result r = run_one(kZ1, kZ2, p);
  EXPECT_NEAR(r.sigma1[0], std::sqrt(10.0 / 5.0), 1e-13);
  EXPECT_NEAR(r.sigma2[0], std::sqrt(40.0 / 8.0), 1e-13);
  const double expected = kZ95 * std::sqrt(2.0 / 5 + 5.0 / 8);
  EXPECT_NEAR(r.lod[0], expected, 1e-12 * expected);
}

TEST(Lod, SignificantIffAbsDistanceExceedsLod) {
  // Same spreads, shift 1 instead of 10: LOD ~ 2.1 > 1, not significant.
  std::vector<double> z2 = kZ2;
  for (double& v : z2) v -= 9.0;
  const Result r = run_one(kZ1, z2, vertical_params());
  ASSERT_EQ(r.status[0], PointStatus::kOk);
  EXPECT_NEAR(r.distance[0], 1.0, 1e-13);
  EXPECT_GT(r.lod[0], 1.0);
  EXPECT_EQ(r.significant[0], 0);
  // Negative distances use |distance|: shift -10.
  for (double& v : z2) v -= 11.0;
  const Result r2 = run_one(kZ1, z2, vertical_params());
  EXPECT_NEAR(r2.distance[0], -10.0, 1e-13);
  EXPECT_EQ(r2.significant[0], 1);
}

TEST(Lod, WelchTWithEq2DegreesOfFreedomWhenCylindersAreSmall) {
  // n1 = n2 = 6 and equal sample variances (70/5 = 14): DF = (2a)^2 / (2 a^2 / 5) = 10 exactly.
  const std::vector<double> z1 = {-5, -3, -1, 1, 3, 5};
  const std::vector<double> z2 = {15, 17, 19, 21, 23, 25};
  ASSERT_DOUBLE_EQ(sample_var(z1), 14.0);
  ASSERT_DOUBLE_EQ(sample_var(z2), 14.0);
  Params p = vertical_params();
  p.lod = Lod::kAuto;
  const Result r = run_one(z1, z2, p);
  const double expected = kT975df10 * std::sqrt(14.0 / 6 + 14.0 / 6);
  // Rounding of the quantile computation (boost/iterative inverse): 1e-10 relative.
  EXPECT_NEAR(r.lod[0], expected, 1e-10 * expected);
  // Without the option the z value is used.
  p.lod = Lod::kZ;
  const Result rz = run_one(z1, z2, p);
  EXPECT_NEAR(rz.lod[0], kZ95 * std::sqrt(14.0 / 3), 1e-12 * rz.lod[0]);
}

TEST(Lod, WelchTAt99PercentWithTwentyDegreesOfFreedom) {
  // n1 = n2 = 11, equal variances: DF = 2 (n - 1) = 20.
  std::vector<double> z1, z2;
  for (int k = -5; k <= 5; ++k) {
    z1.push_back(k);
    z2.push_back(30.0 - k);
  }
  Params p = vertical_params();
  p.lod = Lod::kAuto;
  p.confidence = 0.99;
  const Result r = run_one(z1, z2, p);
  const double v = sample_var(z1);  // 11
  const double expected = kT995df20 * std::sqrt(2 * v / 11);
  EXPECT_NEAR(r.lod[0], expected, 1e-10 * expected);
}

TEST(Lod, WelchTWithNonIntegerDegreesOfFreedom) {
  // a1 = 2.5 / 5, a2 = (40/7) / 8: DF from eq. (2) computed here = 10.89098250336474.
  const double a1 = 2.5 / 5, a2 = (40.0 / 7.0) / 8;
  const double df = (a1 + a2) * (a1 + a2) / (a1 * a1 / 4 + a2 * a2 / 7);
  ASSERT_NEAR(df, 10.890982503364738, 1e-12);
  Params p = vertical_params();
  p.lod = Lod::kAuto;
  const Result r = run_one(kZ1, kZ2, p);
  const double expected = kT975df10_89098 * std::sqrt(a1 + a2);
  EXPECT_NEAR(r.lod[0], expected, 1e-10 * expected);
}

TEST(Lod, TStatisticNotUsedWhenBothCylindersHaveAtLeast30Points) {
  std::vector<double> z1, z2;
  for (int k = 0; k < 30; ++k) {
    z1.push_back(0.1 * k);
    z2.push_back(5.0 + 0.2 * k);
  }
  Params p = vertical_params();
  p.lod = Lod::kAuto;
  const Result r = run_one(z1, z2, p);
  ASSERT_EQ(r.n1[0], 30u);
  ASSERT_EQ(r.n2[0], 30u);
  const double expected = kZ95 * std::sqrt(sample_var(z1) / 30 + sample_var(z2) / 30);
  EXPECT_NEAR(r.lod[0], expected, 1e-12 * expected);
  // One cylinder below 30 is enough to switch to t: LOD must grow.
  z1.pop_back();
  const Result rt = run_one(z1, z2, p);
  const double zlod = kZ95 * std::sqrt(sample_var(z1) / 29 + sample_var(z2) / 30);
  EXPECT_GT(rt.lod[0], zlod * (1 + 1e-6));
}

TEST(Lod, CloudCompareMedianLodUsesIqrOverKIqrToSigmaAsAMeansSpread) {
  // Cloud 1 (n = 6, shuffled): sorted 0 1 3 7 15 31. numpy linear percentiles: median at
  // position 2.5 -> 5; q25 at 1.25 -> 1.5; q75 at 3.75 -> 13; IQR 11.5.
  // Cloud 2 (n = 5): sorted 100 102 103 110 111: median 103, q25 102, q75 110, IQR 8.
  const std::vector<double> z1 = {15, 0, 31, 3, 1, 7};
  const std::vector<double> z2 = {110, 103, 100, 111, 102};
  Params p = vertical_params();
  p.statistic = Statistic::kMedian;
  p.median_lod = MedianLod::kCloudCompare;
  const Result r = run_one(z1, z2, p);
  ASSERT_EQ(r.status[0], PointStatus::kOk);
  EXPECT_NEAR(r.i1[0], 5.0, 1e-13);
  EXPECT_NEAR(r.i2[0], 103.0, 1e-12);
  EXPECT_NEAR(r.distance[0], 98.0, 1e-12);
  const double s1 = 11.5 / kIqrToSigma, s2 = 8.0 / kIqrToSigma;
  EXPECT_NEAR(r.sigma1[0], s1, 1e-12);
  EXPECT_NEAR(r.sigma2[0], s2, 1e-12);
  const double expected = kZ95 * std::sqrt(s1 * s1 / 6 + s2 * s2 / 5);
  EXPECT_NEAR(r.lod[0], expected, 1e-12 * expected);
}

/// Brute-force oracle: the variance of the m-th order statistic (m = floor(n / 2 + 1 / 2)) over
/// all n^n equally likely bootstrap resamples of `values`, enumerated one by one.
double exact_bootstrap_median_variance(std::vector<double> values) {
  const std::size_t n = values.size(), m = n / 2 + (n % 2);  // floor(n / 2 + 1 / 2), 1-based
  std::vector<std::size_t> pick(n, 0);
  std::vector<double> draw(n);
  double sum = 0, sum2 = 0, count = 0;
  for (;;) {
    for (std::size_t k = 0; k < n; ++k) draw[k] = values[pick[k]];
    std::nth_element(draw.begin(), draw.begin() + (m - 1), draw.end());
    sum += draw[m - 1], sum2 += draw[m - 1] * draw[m - 1], count += 1;
    std::size_t k = 0;
    while (k < n && ++pick[k] == n) pick[k++] = 0;
    if (k == n) break;
  }
  return sum2 / count - (sum / count) * (sum / count);
}

TEST(Lod, MedianLodIsZTimesTheExactBootstrapStandardErrorOfTheMedian) {
  // n = 5 and 7 (odd: the median is the middle order statistic); the oracle enumerates all
  // 5^5 and 7^7 resamples. The sigma columns stay IQR / kIqrToSigma.
  const std::vector<double> z1 = {15, 0, 31, 3, 1};
  const std::vector<double> z2 = {110, 103, 100, 111, 102, 95, 130};
  Params p = vertical_params();
  p.statistic = Statistic::kMedian;
  for (const Lod lod : {Lod::kZ, Lod::kAuto}) {  // auto: z for this median (docs/algorithm.md#6.4)
    p.lod = lod;
    const Result r = run_one(z1, z2, p);
    ASSERT_EQ(r.status[0], PointStatus::kOk);
    EXPECT_DOUBLE_EQ(r.distance[0], 103.0 - 3.0);
    EXPECT_NEAR(r.sigma1[0], (15.0 - 1.0) / kIqrToSigma, 1e-12);
    const double v1 = exact_bootstrap_median_variance(z1), v2 = exact_bootstrap_median_variance(z2);
    const double expected = kZ95 * std::sqrt(v1 + v2);
    EXPECT_NEAR(r.lod[0], expected, 1e-12 * expected);
  }
  // Welch t on the same standard errors, eq. (2) with se_k^2 in place of sigma_k^2 / n_k.
  p.lod = Lod::kT;
  const Result rt = run_one(z1, z2, p);
  const Result rz = run_one(z1, z2, [&] {
    Params q = p;
    q.lod = Lod::kZ;
    return q;
  }());
  EXPECT_GT(rt.lod[0], rz.lod[0] * 1.05);
}

TEST(Lod, TUsesWelchAtEveryNAndAutoOnlyBelowThirty) {
  std::vector<double> z1, z2;
  for (int k = -15; k < 15; ++k) {
    z1.push_back(k);
    z2.push_back(40.0 - k);
  }
  Params p = vertical_params();
  const double v = sample_var(z1), se = std::sqrt(2 * v / 30);
  p.lod = Lod::kAuto;
  EXPECT_NEAR(run_one(z1, z2, p).lod[0], kZ95 * se, 1e-12 * se);
  p.lod = Lod::kT;
  // Equal variances, n = 30: DF = 58; t_0.975(58) = 2.001717484145236.
  EXPECT_NEAR(run_one(z1, z2, p).lod[0], 2.001717484145236 * se, 1e-9 * se);
}

TEST(Lod, BootstrapNeedsAtLeastTwoResamples) {
  Params p = vertical_params();
  p.lod = Lod::kBootstrap;
  p.bootstrap_samples = 1;
  EXPECT_THROW(run_one(kZ1, kZ2, p), InvalidArgument);
  p.bootstrap_samples = 0;
  EXPECT_THROW(run_one(kZ1, kZ2, p), InvalidArgument);
}

TEST(Lod, KIqrToSigmaIsTwicePhiInverseOfThreeQuarters) {
  // 2 * 0.6744897501960817 (Phi^-1(0.75)).
  EXPECT_NEAR(kIqrToSigma, 2 * 0.6744897501960817, 1e-15);
}

// --- Bootstrap (Appendix B) ---------------------------------------------------------------

struct BootstrapScene {
  Cloud ref, cmp, cores;
};

// `clusters` separate cylinders 10 apart along x, each with n Gaussian points per cloud
// (sigma 1 in the reference, 2 in the compared, offset 3).
BootstrapScene bootstrap_scene(std::size_t clusters, std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  BootstrapScene s;
  for (std::size_t c = 0; c < clusters; ++c) {
    const Vec3 centre(10.0 * static_cast<double>(c), 0, 0);
    std::vector<double> z1(n), z2(n);
    for (double& v : z1) v = g(rng);
    for (double& v : z2) v = 3.0 + 2.0 * g(rng);
    s.ref.append(axis_cluster(z1, centre));
    s.cmp.append(axis_cluster(z2, centre));
    s.cores.add(centre);
  }
  return s;
}

TEST(LodBootstrap, SameLodFor1And2And8Threads) {
  const BootstrapScene s = bootstrap_scene(64, 50, 11);
  Params p = vertical_params();
  p.lod = Lod::kBootstrap;
  p.bootstrap_samples = 200;
  p.bootstrap_seed = 12345;
  const Result r1 = compute(s.ref.view(), s.cmp.view(), s.cores.view(), p, with_threads(1));
  const Result r2 = compute(s.ref.view(), s.cmp.view(), s.cores.view(), p, with_threads(2));
  const Result r8 = compute(s.ref.view(), s.cmp.view(), s.cores.view(), p, with_threads(8));
  for (std::size_t i = 0; i < r1.size(); ++i) ASSERT_EQ(r1.status[i], PointStatus::kOk) << i;
  EXPECT_TRUE(BitIdentical(r1.lod, r2.lod));
  EXPECT_TRUE(BitIdentical(r1.lod, r8.lod));
  EXPECT_TRUE(BitIdentical(r1.significant, r8.significant));
}

TEST(LodBootstrap, SeedChangesTheResamples) {
  const BootstrapScene s = bootstrap_scene(8, 50, 11);
  Params p = vertical_params();
  p.lod = Lod::kBootstrap;
  p.bootstrap_samples = 200;
  p.bootstrap_seed = 1;
  const Result a = compute(s.ref.view(), s.cmp.view(), s.cores.view(), p, with_threads(1));
  p.bootstrap_seed = 2;
  const Result b = compute(s.ref.view(), s.cmp.view(), s.cores.view(), p, with_threads(1));
  bool any_differs = false;
  for (std::size_t i = 0; i < a.size(); ++i) any_differs |= a.lod[i] != b.lod[i];
  EXPECT_TRUE(any_differs);
}

TEST(LodBootstrap, WithinTenPercentOfParametricOnGaussianData) {
  // n = 200 per cylinder, 1000 resamples: the relative standard error of a bootstrap standard
  // deviation is about 1 / sqrt(2 * 1000) = 2.2 %, so 10 % is > 4 standard errors.
  const BootstrapScene s = bootstrap_scene(4, 200, 2024);
  Params p = vertical_params();
  const Result param = compute(s.ref.view(), s.cmp.view(), s.cores.view(), p);
  p.lod = Lod::kBootstrap;
  p.bootstrap_samples = 1000;
  p.bootstrap_seed = 7;
  const Result boot = compute(s.ref.view(), s.cmp.view(), s.cores.view(), p);
  for (std::size_t i = 0; i < s.cores.size(); ++i) {
    ASSERT_EQ(boot.status[i], PointStatus::kOk);
    EXPECT_EQ(boot.n1[i], 200u);
    EXPECT_NEAR(boot.lod[i], param.lod[i], 0.10 * param.lod[i]) << "core " << i;
    EXPECT_NE(boot.lod[i], param.lod[i]) << "bootstrap LOD identical to the parametric one";
    // The distance itself is still i2 - i1 of the full cylinders.
    EXPECT_DOUBLE_EQ(boot.distance[i], param.distance[i]);
  }
}

TEST(LodBootstrap, RegistrationErrorAddedInsideTheParentheses) {
  const BootstrapScene s = bootstrap_scene(4, 60, 5);
  Params p = vertical_params();
  p.lod = Lod::kBootstrap;
  p.bootstrap_samples = 300;
  p.bootstrap_seed = 99;
  const Result a = compute(s.ref.view(), s.cmp.view(), s.cores.view(), p);
  p.registration_error = 0.25;
  const Result b = compute(s.ref.view(), s.cmp.view(), s.cores.view(), p);
  for (std::size_t i = 0; i < a.size(); ++i)
    EXPECT_NEAR(b.lod[i] - a.lod[i], kZ95 * 0.25, 1e-12) << i;  // same seed, same resamples
}

}  // namespace
}  // namespace m3c2::test
