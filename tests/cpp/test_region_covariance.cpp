// region_covariance_sum (bins) against region_covariance_exact (every pair, O(N^2)) on uniform,
// clustered and lattice points; the exact sum against hand-worked cases; the same bits for any
// thread count; bad inputs refused.

#include <m3c2/errors.hpp>
#include <m3c2/region_covariance.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

namespace m3c2::test {
namespace {

using K = CovarianceKind;
using Model = std::vector<CovarianceComponent>;

std::vector<double> uniform_points(std::size_t n, double side, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, side);
  std::vector<double> xy;
  for (std::size_t i = 0; i < 2 * n; ++i) xy.push_back(u(rng) + 4.0e5);  // UTM-sized offset
  return xy;
}

std::vector<double> lattice(int cols, int rows, double step) {
  std::vector<double> xy;
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) xy.push_back(5.0e5 + (c + 0.5) * step), xy.push_back(4.2e6 + (r + 0.5) * step);
  return xy;
}

/// Gaussian clusters: densities that change within a bin
std::vector<double> clustered(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 3.0);
  std::uniform_real_distribution<double> u(0.0, 60.0);
  std::vector<double> xy;
  for (int k = 0; k < 8; ++k) {
    const double x = u(rng), y = u(rng);
    for (std::size_t i = 0; i < n / 8; ++i) xy.push_back(x + g(rng)), xy.push_back(y + g(rng));
  }
  return xy;
}

double relative_error(const std::vector<double>& xy, const std::vector<CovarianceComponent>& model) {
  const double exact = region_covariance_exact(xy, model);
  const double binned = region_covariance_sum(xy, model).sum;
  const double e = std::abs(binned - exact) / exact;
  std::printf("relative error %.3g\n", e);  // the figure docs/algorithm.md states
  return e;
}

// The bins' stated accuracy (docs/algorithm.md, "Aggregates over a region"): within 0.05 % of the
// exact sum; the exponential's dropped tail (8e-5) included.
constexpr double kTolerance = 5e-4;  // measured: at most 8e-5 on these cases

TEST(RegionCovariance, BinsMatchTheExactSumOnUniformPoints) {
  const auto xy = uniform_points(3000, 60.0, 34);
  EXPECT_LT(relative_error(xy, Model{{K::kSpherical, 4e-4, 10.0}}), kTolerance);
  EXPECT_LT(relative_error(xy, Model{{K::kExponential, 1e-4, 6.0}}), kTolerance);
  EXPECT_LT(relative_error(xy, Model{{K::kSpherical, 2e-4, 3.0}, {K::kExponential, 1e-4, 25.0}}), kTolerance);
}

TEST(RegionCovariance, BinsMatchTheExactSumOnClusteredPoints) {
  const auto xy = clustered(4000, 7);
  EXPECT_LT(relative_error(xy, Model{{K::kSpherical, 1.0, 8.0}}), kTolerance);
  EXPECT_LT(relative_error(xy, Model{{K::kExponential, 1.0, 4.0}}), kTolerance);
}

TEST(RegionCovariance, BinsMatchTheExactSumOnAGridRunsLattice) {
  // core points of a grid run (--grid 1): a range of a few cells, and of many
  const auto xy = lattice(70, 50, 1.0);
  EXPECT_LT(relative_error(xy, Model{{K::kSpherical, 1.0, 4.0}}), kTolerance);
  EXPECT_LT(relative_error(xy, Model{{K::kExponential, 1.0, 20.0}}), kTolerance);
}

TEST(RegionCovariance, ExactSumOfHandWorkedCases) {
  const std::vector<CovarianceComponent> model{{K::kSpherical, 2.0, 10.0}, {K::kExponential, 0.5, 3.0}};
  const std::vector<double> one{1.0, 2.0};
  EXPECT_DOUBLE_EQ(region_covariance_exact(one, model), 2.5);
  EXPECT_DOUBLE_EQ(region_covariance_sum(one, model).sum, 2.5);
  const std::vector<double> two{0.0, 0.0, 3.0, 4.0};  // 5 apart
  const double c5 = 2.0 * (1 - 1.5 * 0.5 + 0.5 * 0.125) + 0.5 * std::exp(-5.0);
  EXPECT_NEAR(region_covariance_exact(two, model), 2 * 2.5 + 2 * c5, 1e-14);
  // far apart: only C(0) on the diagonal for the spherical; both sums agree
  const std::vector<double> far{0.0, 0.0, 100.0, 0.0};
  EXPECT_NEAR(region_covariance_exact(far, Model{{K::kSpherical, 2.0, 10.0}}), 4.0, 1e-14);
  EXPECT_NEAR(region_covariance_sum(far, Model{{K::kSpherical, 2.0, 10.0}}).sum, 4.0, 1e-14);
  EXPECT_EQ(region_covariance_sum({}, model).sum, 0.0);
}

TEST(RegionCovariance, SameBitsForAnyThreadCount) {
  const auto xy = uniform_points(20000, 200.0, 3);
  const std::vector<CovarianceComponent> model{{K::kSpherical, 1.0, 5.0}, {K::kExponential, 1.0, 30.0}};
  RunOptions one, three;
  one.threads = 1, three.threads = 3;
  const auto a = region_covariance_sum(xy, model, {}, one);
  const auto b = region_covariance_sum(xy, model, {}, three);
  EXPECT_EQ(a.sum, b.sum);
  EXPECT_EQ(a.bin_side, (std::vector<double>{5.0 / 8, 30.0 / 8}));
  const std::vector<double> small(xy.begin(), xy.begin() + 2000);
  EXPECT_EQ(region_covariance_exact(small, model, one), region_covariance_exact(small, model, three));
}

TEST(RegionCovariance, TooManyBinsMakesThemLarger) {
  const auto xy = uniform_points(2000, 60.0, 5);
  CovarianceSumOptions options;
  options.max_bins = 100;
  const auto r = region_covariance_sum(xy, Model{{K::kSpherical, 1.0, 8.0}}, options);
  ASSERT_EQ(r.bin_side.size(), 1u);
  EXPECT_GT(r.bin_side[0], 1.0);
  EXPECT_LE(std::pow(std::floor(60.0 / r.bin_side[0]) + 1, 2), 100.0);
}

TEST(RegionCovariance, BadInputsRefused) {
  const std::vector<CovarianceComponent> ok{{K::kSpherical, 1.0, 1.0}};
  EXPECT_THROW(region_covariance_sum(std::vector<double>{1.0, 2.0, 3.0}, ok), InvalidArgument);
  EXPECT_THROW(region_covariance_sum(std::vector<double>{1.0, NAN}, ok), InvalidArgument);
  EXPECT_THROW(region_covariance_sum(std::vector<double>{1.0, 2.0}, Model{{K::kSpherical, -1.0, 1.0}}),
               InvalidArgument);
  EXPECT_THROW(region_covariance_sum(std::vector<double>{1.0, 2.0}, Model{{K::kSpherical, 1.0, 0.0}}), InvalidArgument);
  CovarianceSumOptions bad;
  bad.bin_fraction = 0;
  EXPECT_THROW(region_covariance_sum(std::vector<double>{1.0, 2.0}, ok, bad), InvalidArgument);
  EXPECT_THROW(region_covariance_exact(std::vector<double>{1.0, NAN}, ok), InvalidArgument);
}

}  // namespace
}  // namespace m3c2::test
