// p-values of every LOD model (docs/algorithm.md, "p-values") against independent computations
// (closed forms: erfc, the incomplete beta and gamma functions, not the engine's Boost
// distributions), and the contract p < 1 - confidence <=> significant on random scenes and on
// distances at the LOD itself, its neighbouring doubles included.

#include "test_support.hpp"

#include "uncertainty/p_value.hpp"

#include <boost/math/special_functions/beta.hpp>
#include <boost/math/special_functions/erf.hpp>
#include <boost/math/special_functions/gamma.hpp>

#include <Eigen/Cholesky>

#include <algorithm>
#include <random>

namespace m3c2::test {
namespace {

// A row of core points 2 apart on the x axis, each with its own cylinder contents: n points per
// cloud on a small circle about the axis (vertical normals imposed: the position along the normal
// is z), normal noise of a random spread, and a random change (a third of them none).
struct Scene {
  Cloud reference, compared, core;
};

Scene random_scene(std::uint32_t seed, std::size_t cores, std::uint32_t n_min, std::uint32_t n_max) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<std::uint32_t> count(n_min, n_max);
  std::uniform_real_distribution<double> spread(0.005, 0.05), change(-0.08, 0.08), unit(0.0, 1.0);
  std::normal_distribution<double> gauss(0.0, 1.0);
  Scene s;
  for (std::size_t c = 0; c < cores; ++c) {
    const double x = 2.0 * double(c);
    s.core.add(x, 0.0, 0.0);
    const double shift = unit(rng) < 1.0 / 3.0 ? 0.0 : change(rng);
    for (int k = 0; k < 2; ++k) {
      const std::uint32_t n = count(rng);
      const double sd = spread(rng);
      for (std::uint32_t j = 0; j < n; ++j) {
        const double a = 0.61 * double(j) + 0.3 * double(k);
        const Vec3 p(x + 0.05 * std::cos(a), 0.05 * std::sin(a), (k == 1 ? shift : 0.0) + sd * gauss(rng));
        (k == 0 ? s.reference : s.compared).add(p);
      }
    }
  }
  return s;
}

Params vertical() {
  Params p;
  p.normal_diameters = {1.0};
  p.normal_source = NormalSource::kVertical;
  p.projection_diameter = 0.2;
  p.max_depth = 1.0;
  return p;
}

/// Two-sided normal tail from erfc (the engine uses Boost's normal distribution).
double normal_p(double t) { return std::erfc(t / std::sqrt(2.0)); }
/// Two-sided Student tail: P(|t_v| >= t) = I_{v / (v + t^2)}(v / 2, 1 / 2).
double student_p(double t, double v) { return boost::math::ibeta(v / 2.0, 0.5, v / (v + t * t)); }
/// Chi-square tail with k dof: Q(k / 2, x / 2), the regularised upper incomplete gamma function.
double chi2_p(double x, double k) { return boost::math::gamma_q(k / 2.0, x / 2.0); }

/// The contract on every core point, and p against `expected(i)` where the LOD is defined.
template <class Expected>
void check(const Result& r, double confidence, Expected expected, double tolerance) {
  const double alpha = 1.0 - confidence;
  std::size_t defined = 0, significant = 0;
  for (std::size_t i = 0; i < r.size(); ++i) {
    if (std::isnan(r.lod[i])) {
      EXPECT_TRUE(std::isnan(r.p_value[i])) << i;
      EXPECT_EQ(r.significant[i], 0) << i;
      continue;
    }
    ++defined;
    significant += r.significant[i];
    ASSERT_EQ(r.p_value[i] < alpha, r.significant[i] == 1) << i << " p " << r.p_value[i];
    EXPECT_GE(r.p_value[i], 0.0);
    EXPECT_LE(r.p_value[i], 1.0);
    const double want = expected(i);
    EXPECT_NEAR(r.p_value[i], want, tolerance * std::max(want, 1e-300) + 1e-15) << i;
  }
  // The scenes hold both outcomes, so that the contract is tested on each side.
  EXPECT_GT(defined, r.size() / 2);
  EXPECT_GT(significant, 0u);
  EXPECT_LT(significant, defined);
}

double se(const Result& r, std::size_t i, int k) {
  return k == 1 ? r.sigma1[i] / std::sqrt(double(r.n1[i])) : r.sigma2[i] / std::sqrt(double(r.n2[i]));
}

TEST(PValue, NormalEq1) {
  const Scene s = random_scene(11, 300, 2, 60);
  Params p = vertical();
  p.lod = Lod::kZ;
  p.registration_error = 0.004;
  const Result r = compute(s.reference.view(), s.compared.view(), s.core.view(), p);
  check(
      r, p.confidence,
      [&](std::size_t i) {
        const double scale = std::hypot(se(r, i, 1), se(r, i, 2)) + p.registration_error;
        return normal_p(std::abs(r.distance[i]) / scale);
      },
      1e-9);
}

TEST(PValue, WelchT) {
  const Scene s = random_scene(12, 300, 2, 20);
  Params p = vertical();
  p.lod = Lod::kT;
  p.min_points = 2;
  p.confidence = 0.99;
  const Result r = compute(s.reference.view(), s.compared.view(), s.core.view(), p);
  check(
      r, p.confidence,
      [&](std::size_t i) {
        const double a = se(r, i, 1) * se(r, i, 1), b = se(r, i, 2) * se(r, i, 2);
        const double v = (a + b) * (a + b) / (a * a / (r.n1[i] - 1.0) + b * b / (r.n2[i] - 1.0));
        return student_p(std::abs(r.distance[i]) / std::sqrt(a + b), v);
      },
      1e-9);
}

TEST(PValue, AutoRuleTakesTBelowThirty) {
  const Scene s = random_scene(13, 200, 5, 60);
  Params p = vertical();
  p.lod = Lod::kAuto;
  const Result r = compute(s.reference.view(), s.compared.view(), s.core.view(), p);
  check(
      r, p.confidence,
      [&](std::size_t i) {
        const double a = se(r, i, 1) * se(r, i, 1), b = se(r, i, 2) * se(r, i, 2),
                     t = std::abs(r.distance[i]) / std::sqrt(a + b);
        if (r.n1[i] >= 30 && r.n2[i] >= 30) return normal_p(t);
        return student_p(t, (a + b) * (a + b) / (a * a / (r.n1[i] - 1.0) + b * b / (r.n2[i] - 1.0)));
      },
      1e-9);
}

TEST(PValue, BootstrapInvertsItsLod) {
  // The bootstrap LOD is z (sigma_b + reg): its test rejects when |d| / (sigma_b + reg) > z, so
  // p = 2 (1 - Phi(z |d| / LOD)), from the LOD column alone.
  const Scene s = random_scene(14, 120, 5, 30);
  Params p = vertical();
  p.lod = Lod::kBootstrap;
  p.bootstrap_samples = 200;
  p.bootstrap_seed = 7;
  p.registration_error = 0.002;
  const double z = 1.959963984540054;
  const Result r = compute(s.reference.view(), s.compared.view(), s.core.view(), p);
  check(
      r, p.confidence, [&](std::size_t i) { return normal_p(z * std::abs(r.distance[i]) / r.lod[i]); }, 1e-9);
}

TEST(PValue, MedianLods) {
  const double z = 1.959963984540054;
  for (const MedianLod m : {MedianLod::kMaritzJarrett, MedianLod::kCloudCompare}) {
    const Scene s = random_scene(15, 200, 5, 60);
    Params p = vertical();
    p.statistic = Statistic::kMedian;
    p.median_lod = m;
    p.lod = Lod::kZ;
    const Result r = compute(s.reference.view(), s.compared.view(), s.core.view(), p);
    check(
        r, p.confidence, [&](std::size_t i) { return normal_p(z * std::abs(r.distance[i]) / r.lod[i]); }, 1e-9);
    if (m != MedianLod::kCloudCompare) continue;
    for (std::size_t i = 0; i < r.size(); ++i) {  // eq. (1) with sigma = IQR / 1.349 as a mean's spread
      if (!std::isfinite(r.lod[i])) continue;
      EXPECT_NEAR(r.p_value[i], normal_p(std::abs(r.distance[i]) / std::hypot(se(r, i, 1), se(r, i, 2))),
                  1e-9 * r.p_value[i] + 1e-15);
    }
  }
}

TEST(PValue, PrecisionMaps) {
  const Scene s = random_scene(16, 200, 3, 30);
  Params p = vertical();
  p.uncertainty = Uncertainty::kPrecisionMaps;
  p.registration_error = 0.001;
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> sd(0.002, 0.03);
  std::vector<double> prec1(3 * s.reference.size()), prec2(3 * s.compared.size());
  for (double& v : prec1) v = sd(rng);
  for (double& v : prec2) v = sd(rng);
  UncertaintyInputs in;
  in.reference.precision = prec1, in.compared.precision = prec2;
  const Result r = compute(s.reference.view(), s.compared.view(), s.core.view(), p, {}, {}, in);
  check(
      r, p.confidence,
      [&](std::size_t i) {
        return normal_p(std::abs(r.distance[i]) / (std::hypot(r.spread1[i], r.spread2[i]) + p.registration_error));
      },
      1e-9);
}

UncertaintyInputs ep_inputs(const Scene& s, std::vector<std::uint32_t>& ids1, std::vector<std::uint32_t>& ids2) {
  UncertaintyInputs in;
  ScanPosition sp;
  sp.id = 0;
  sp.origin[0] = 100.0, sp.origin[1] = -30.0, sp.origin[2] = 20.0;
  sp.sigma_range = 0.005, sp.sigma_scan = 1e-4, sp.sigma_yaw = 1e-4;
  in.reference.scan_positions = {sp}, in.compared.scan_positions = {sp};
  ids1.assign(s.reference.size(), 0), ids2.assign(s.compared.size(), 0);
  in.reference.scan_position = ids1, in.compared.scan_position = ids2;
  in.covariances = true;
  return in;
}

TEST(PValue, ErrorPropagationProjected) {
  const Scene s = random_scene(17, 200, 3, 30);
  Params p = vertical();
  p.uncertainty = Uncertainty::kErrorPropagation;
  p.ep_covariance = EpCovariance::kIndependent;
  p.ep_lod = EpLod::kProjected;
  std::vector<std::uint32_t> ids1, ids2;
  const UncertaintyInputs in = ep_inputs(s, ids1, ids2);
  const Result r = compute(s.reference.view(), s.compared.view(), s.core.view(), p, {}, {}, in);
  check(
      r, p.confidence,
      [&](std::size_t i) { return normal_p(std::abs(r.distance[i]) / std::hypot(r.spread1[i], r.spread2[i])); }, 1e-9);
}

TEST(PValue, ErrorPropagationPublished) {
  // Winiwarter et al. 2021: significant iff d^2 n^T (S1 + S2)^-1 n > chi2(3, confidence).
  const Scene s = random_scene(18, 200, 3, 30);
  Params p = vertical();
  p.uncertainty = Uncertainty::kErrorPropagation;
  p.ep_covariance = EpCovariance::kIndependent;
  p.ep_lod = EpLod::kPublished;
  std::vector<std::uint32_t> ids1, ids2;
  const UncertaintyInputs in = ep_inputs(s, ids1, ids2);
  const Result r = compute(s.reference.view(), s.compared.view(), s.core.view(), p, {}, {}, in);
  check(
      r, p.confidence,
      [&](std::size_t i) {
        Eigen::Matrix3d sum;
        for (int e = 0; e < 9; ++e) sum(e / 3, e % 3) = r.covariance1[9 * i + e] + r.covariance2[9 * i + e];
        const Vec3 n(r.normal[3 * i], r.normal[3 * i + 1], r.normal[3 * i + 2]);
        const double w = n.dot(sum.ldlt().solve(n));
        return chi2_p(r.distance[i] * r.distance[i] * w, 3.0);
      },
      1e-7);
}

TEST(PValue, NaNWhereTheLodIsNaN) {
  // Cylinders with one point (below min_points) and an empty one: LOD NaN, p NaN.
  Scene s = random_scene(19, 4, 1, 1);
  Params p = vertical();
  s.core.add(1000.0, 0.0, 0.0);  // empty cylinders
  const Result r = compute(s.reference.view(), s.compared.view(), s.core.view(), p);
  for (std::size_t i = 0; i < r.size(); ++i) {
    EXPECT_TRUE(std::isnan(r.lod[i]));
    EXPECT_TRUE(std::isnan(r.p_value[i]));
    EXPECT_NE(r.status[i], PointStatus::kOk);
  }
}

// decide() where |d| is the LOD itself or one of its neighbouring doubles: the LOD's rule decides,
// p lies on the same side of alpha, and by at most the rounding that separates the two.
TEST(PValue, ContractAtTheBoundary) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> scale_of(1e-4, 10.0), conf_of(0.5, 0.999);
  std::size_t nudged = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    const double confidence = conf_of(rng), alpha = 1.0 - confidence, scale = scale_of(rng);
    detail::LodTest test;
    double critical;
    switch (trial % 3) {
      case 0: critical = std::sqrt(2.0) * boost::math::erfc_inv(alpha); break;
      case 1:
        test.law = {detail::TestLaw::Kind::kStudent, 2.0 + trial % 37};
        critical = std::sqrt(test.law.dof * (1.0 / boost::math::ibeta_inv(test.law.dof / 2.0, 0.5, alpha) - 1.0));
        break;
      default:
        test.law = {detail::TestLaw::Kind::kChiSquared, 3.0};
        critical = std::sqrt(2.0 * boost::math::gamma_q_inv(1.5, alpha));
        break;
    }
    test.scale = scale, test.lod = critical * scale;
    Result r;
    r.resize(1);
    for (const double d : {test.lod, std::nextafter(test.lod, 0.0), std::nextafter(test.lod, 1e300),
                           std::nextafter(std::nextafter(test.lod, 1e300), 1e300), -test.lod}) {
      r.distance[0] = d;
      detail::decide(test, alpha, 0, r);
      ASSERT_EQ(r.significant[0], std::abs(d) > test.lod ? 1 : 0);
      ASSERT_EQ(r.p_value[0] < alpha, r.significant[0] == 1) << trial << " d " << d;
      const double raw = detail::tail_probability(std::abs(d) / scale, test.law);
      EXPECT_NEAR(r.p_value[0], raw, 1e-9 * alpha) << trial;
      nudged += r.p_value[0] != raw;
    }
  }
  EXPECT_GT(nudged, 0u);  // the boundary is met: the nudge is exercised, not only described
}

TEST(PValue, ZeroScale) {
  // Both spreads 0 and reg 0: the LOD is 0; d = 0 is not significant (p = 1), d != 0 is (p = 0).
  detail::LodTest test;
  test.scale = 0.0, test.lod = 0.0;
  Result r;
  r.resize(1);
  r.distance[0] = 0.0;
  detail::decide(test, 0.05, 0, r);
  EXPECT_EQ(r.significant[0], 0);
  EXPECT_EQ(r.p_value[0], 1.0);
  r.distance[0] = 1e-9;
  detail::decide(test, 0.05, 0, r);
  EXPECT_EQ(r.significant[0], 1);
  EXPECT_EQ(r.p_value[0], 0.0);
}

}  // namespace
}  // namespace m3c2::test
