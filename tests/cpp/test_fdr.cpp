// fdr_q_values() against the step-up procedures themselves (Benjamini & Hochberg 1995, their
// theorem's rule; Benjamini & Yekutieli 2001, BH at Q / c(m)) and against the O(m^2) definition
// q_(i) = min_{j >= i} min(1, max(p_(j), c m p_(j) / j)): ties, NaN, the order of the input.

#include "test_support.hpp"

#include <algorithm>
#include <numeric>
#include <random>

namespace m3c2::test {
namespace {

/// The step-up procedure's rejections at level q: the largest k with p_(k) <= k q / m, and every
/// p <= p_(k) (Benjamini & Hochberg 1995, section 3). c > 1: Benjamini & Yekutieli's level q / c.
std::vector<bool> step_up(const std::vector<double>& p, double q, double c) {
  std::vector<double> sorted;
  for (double v : p)
    if (std::isfinite(v)) sorted.push_back(v);
  std::sort(sorted.begin(), sorted.end());
  const double m = double(sorted.size());
  double threshold = -1.0;
  for (std::size_t k = sorted.size(); k >= 1; --k)
    if (sorted[k - 1] <= double(k) * q / (m * c)) {
      threshold = sorted[k - 1];
      break;
    }
  std::vector<bool> out(p.size());
  for (std::size_t i = 0; i < p.size(); ++i) out[i] = std::isfinite(p[i]) && p[i] <= threshold;
  return out;
}

std::vector<double> brute_force(const std::vector<double>& p, double c) {
  std::vector<std::size_t> idx;
  for (std::size_t i = 0; i < p.size(); ++i)
    if (std::isfinite(p[i])) idx.push_back(i);
  std::stable_sort(idx.begin(), idx.end(), [&](std::size_t a, std::size_t b) { return p[a] < p[b]; });
  const double m = double(idx.size());
  std::vector<double> q(p.size(), kNaN);
  for (std::size_t i = 0; i < idx.size(); ++i) {
    double best = 1.0;
    for (std::size_t j = i; j < idx.size(); ++j)
      best = std::min(best, std::max(p[idx[j]], c * (m * p[idx[j]] / double(j + 1))));
    q[idx[i]] = best;
  }
  return q;
}

std::vector<double> random_p(std::uint32_t seed, std::size_t m) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> p(m);
  for (double& v : p) {
    const double x = u(rng);
    v = x < 0.3 ? 1e-4 * u(rng) : x < 0.4 ? kNaN : x < 0.5 ? 0.01 : u(rng);  // signal, NaN, ties, null
  }
  return p;
}

double harmonic(std::size_t m) {
  double c = 0.0;
  for (std::size_t i = m; i >= 1; --i) c += 1.0 / double(i);
  return c;
}

TEST(Fdr, MatchesTheStepUpProcedure) {
  for (std::uint32_t seed = 1; seed <= 20; ++seed) {
    const std::vector<double> p = random_p(seed, 50 + 13 * seed);
    std::size_t finite = 0;
    for (double v : p) finite += std::isfinite(v);
    for (const auto method : {FdrMethod::kBenjaminiHochberg, FdrMethod::kBenjaminiYekutieli}) {
      const double c = method == FdrMethod::kBenjaminiHochberg ? 1.0 : harmonic(finite);
      const std::vector<double> q = fdr_q_values(p, method);
      const std::vector<double> want = brute_force(p, c);
      for (std::size_t i = 0; i < p.size(); ++i) {
        if (std::isnan(p[i])) {
          EXPECT_TRUE(std::isnan(q[i]));
          continue;
        }
        EXPECT_DOUBLE_EQ(q[i], want[i]) << seed << " " << i;
        EXPECT_GE(q[i], p[i]);
        EXPECT_LE(q[i], 1.0);
      }
      for (const double level : {0.001, 0.01, 0.05, 0.1, 0.2}) {
        const std::vector<bool> rejected = step_up(p, level, c);
        std::size_t r = 0;
        for (std::size_t i = 0; i < p.size(); ++i) {
          EXPECT_EQ(std::isfinite(q[i]) && q[i] <= level, rejected[i]) << seed << " " << level << " " << i;
          r += rejected[i];
        }
        if (level == 0.05 && method == FdrMethod::kBenjaminiHochberg) {
          EXPECT_GT(r, 0u);
        }
      }
    }
  }
}

TEST(Fdr, TiesAndOrderDoNotChangeTheBits) {
  std::vector<double> p = random_p(99, 500);
  const std::vector<double> q = fdr_q_values(p, FdrMethod::kBenjaminiHochberg);
  // A permutation of the core points permutes the q-values, bit for bit.
  std::vector<std::size_t> perm(p.size());
  std::iota(perm.begin(), perm.end(), 0);
  std::shuffle(perm.begin(), perm.end(), std::mt19937_64(4));
  std::vector<double> shuffled(p.size());
  for (std::size_t i = 0; i < p.size(); ++i) shuffled[i] = p[perm[i]];
  const std::vector<double> qs = fdr_q_values(shuffled, FdrMethod::kBenjaminiHochberg);
  for (std::size_t i = 0; i < p.size(); ++i)
    EXPECT_TRUE(BitIdentical(std::vector<double>{qs[i]}, std::vector<double>{q[perm[i]]}));
  // Equal p-values share one q.
  for (std::size_t i = 0; i < p.size(); ++i)
    for (std::size_t j = 0; j < p.size(); ++j)
      if (p[i] == p[j]) {
        ASSERT_EQ(q[i], q[j]);
      }
}

TEST(Fdr, EdgeCases) {
  EXPECT_TRUE(fdr_q_values(std::vector<double>{}, FdrMethod::kBenjaminiHochberg).empty());
  const std::vector<double> nan = fdr_q_values(std::vector<double>{kNaN, kNaN}, FdrMethod::kBenjaminiYekutieli);
  EXPECT_TRUE(std::isnan(nan[0]) && std::isnan(nan[1]));
  // One p: q = p (BH and BY: c(1) = 1).
  EXPECT_EQ(fdr_q_values(std::vector<double>{0.03}, FdrMethod::kBenjaminiYekutieli)[0], 0.03);
  // m = 4, p = (0.01, 0.02, 0.03, 0.5): BH q = (0.04, 0.04, 0.04, 0.5); BY times 25/12.
  const std::vector<double> p = {0.03, 0.5, 0.01, 0.02};
  const std::vector<double> bh = fdr_q_values(p, FdrMethod::kBenjaminiHochberg);
  EXPECT_DOUBLE_EQ(bh[0], 0.04);
  EXPECT_DOUBLE_EQ(bh[1], 0.5);
  EXPECT_DOUBLE_EQ(bh[2], 0.04);
  EXPECT_DOUBLE_EQ(bh[3], 0.04);
  const std::vector<double> by = fdr_q_values(p, FdrMethod::kBenjaminiYekutieli);
  EXPECT_DOUBLE_EQ(by[1], std::min(1.0, 0.5 * 25.0 / 12.0));
  EXPECT_DOUBLE_EQ(by[2], 0.04 * 25.0 / 12.0);
  EXPECT_THROW(fdr_q_values(std::vector<double>{1.5}, FdrMethod::kBenjaminiHochberg), InvalidArgument);
}

}  // namespace
}  // namespace m3c2::test
