// detail::ShellIndex (src/features/shell_index.hpp) against the plain count of the inner radii a squared
// distance exceeds, on the values where a table lookup could go wrong: the radii themselves and
// their neighbouring doubles, bins holding two radii, one scale, radii near under- and overflow.

#include "features/shell_index.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace {

std::size_t counted(const std::vector<double>& r2, double d2) {
  std::size_t r = 0;
  for (std::size_t q = 0; q + 1 < r2.size(); ++q) r += d2 > r2[q];
  return r;
}

/// Every radius, the doubles next to it, 0, and random values in [0, r2.back()].
void expect_counts(const std::vector<double>& r2, std::mt19937_64& rng) {
  const m3c2::detail::ShellIndex shell_of(r2);
  std::vector<double> probes{0.0, r2.back()};
  for (const double v : r2) probes.insert(probes.end(), {v, std::nextafter(v, 0.0), std::nextafter(v, INFINITY)});
  std::uniform_real_distribution<double> u(0.0, r2.back());
  for (int k = 0; k < 2000; ++k) probes.push_back(u(rng));
  for (const double d2 : probes) {
    if (d2 < 0.0 || d2 > r2.back()) continue;  // nextafter past the largest radius
    ASSERT_EQ(shell_of(d2), counted(r2, d2)) << "d2 = " << d2;
  }
}

std::vector<double> squared(std::vector<double> radii) {
  std::sort(radii.begin(), radii.end());
  for (double& r : radii) r *= r;
  return radii;
}

TEST(ShellIndex, EqualsTheCountOverTheRadii) {
  std::mt19937_64 rng(18);
  std::vector<double> canupo;  // the bench's 10 scales
  for (int k = 1; k <= 10; ++k) canupo.push_back(0.125 * k);
  expect_counts(squared(canupo), rng);
  expect_counts(squared({0.7}), rng);       // one scale: always shell 0
  expect_counts(squared({0.5, 2.0}), rng);  // two
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {  // random sets of 2 to 40 scales over 6 decades
    std::vector<double> radii(2 + trial % 39);
    for (double& r : radii) r = std::pow(10.0, -3.0 + 6.0 * u(rng));
    std::sort(radii.begin(), radii.end());
    radii.erase(std::unique(radii.begin(), radii.end()), radii.end());
    expect_counts(squared(radii), rng);
  }
}

TEST(ShellIndex, BinsHoldingSeveralRadiiAreCountedOneByOne) {
  std::mt19937_64 rng(19);
  // Radii a few ulps apart: closer than any table of at most 2^16 bins resolves.
  expect_counts(squared({1.0, std::nextafter(1.0, 2.0), 1.0 + 1e-12, 1.5, 3.0}), rng);
  expect_counts(squared({1e-3, 1e-3 * (1.0 + 1e-9), 1000.0}), rng);
}

TEST(ShellIndex, RadiiNearTheEndsOfTheDoubleRange) {
  std::mt19937_64 rng(20);
  expect_counts(squared({1e-160, 2e-160, 5e-160}), rng);  // squares underflow toward denormals
  expect_counts(squared({1e-200, 1e-170}), rng);          // the smaller square is 0
  expect_counts(squared({1e150, 3e150, 1e152}), rng);
}

}  // namespace
