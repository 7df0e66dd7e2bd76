// normalised_dtw (src/series/dtw.cpp) against the plain full cost matrix of Anders et al. 2021, eq. 3:
// the lower bound (src/series/dtw_bound.hpp) is never above the exact cost, the strips of rows
// (src/series/dtw_rows.hpp) give the same bits as row by row, and the early stops never change a
// comparison with a threshold <= at_least, on seeded random series with NaNs, equal and
// constant series; the pairs computed lanes at a time (src/series/dtw_many.hpp) give the same bits as
// one at a time.

#include <m3c2/objects_by_change.hpp>

#include "dtw_oracle.hpp"
#include "series/dtw_bound.hpp"
#include "series/dtw_many.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

namespace m3c2::test {
namespace {

double full_cost(const std::vector<double>& x, const std::vector<double>& y) { return full_dtw_cost(x, y); }

/// normalised_dtw without any early stop: the full matrix, py4dgeo's normalisation.
double full_normalised(const std::vector<double>& a, const std::vector<double>& b, double norm_a, double norm_b,
                       double origin, std::vector<double>* xs = nullptr, std::vector<double>* ys = nullptr) {
  double dmax = 0.0;
  std::vector<double> x, y;
  for (std::size_t k = 0; k < a.size(); ++k) {
    if (!std::isnan(a[k])) dmax += std::abs(a[k] - origin);
    if (!std::isnan(a[k]) && !std::isnan(b[k])) x.push_back(a[k] - norm_a), y.push_back(b[k] - norm_b);
  }
  if (xs) *xs = x, *ys = y;
  if (x.empty()) return std::numeric_limits<double>::quiet_NaN();
  return std::fmin(1.0, 1.0 - (dmax - full_cost(x, y)) / dmax);
}

bool same_bits(double u, double v) { return std::memcmp(&u, &v, sizeof u) == 0; }

/// Series of the kinds 4D-OBC meets: random walks (similar or not), equal, constant, with gaps.
struct Pair {
  std::vector<double> a, b;
};

Pair random_pair(std::mt19937_64& rng) {
  std::uniform_int_distribution<int> kind(0, 7), length(1, 60);
  std::normal_distribution<double> step(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const std::size_t n = std::size_t(length(rng));
  Pair p{std::vector<double>(n), std::vector<double>(n)};
  const int k = kind(rng);
  const double scale = std::pow(10.0, 4.0 * u(rng) - 2.0), noise = u(rng);
  double va = 0.0, vb = 0.0;
  for (std::size_t e = 0; e < n; ++e) {
    va += scale * step(rng);
    vb = k == 1 ? va + noise * scale * step(rng) : vb + scale * step(rng);
    p.a[e] = va, p.b[e] = vb;
  }
  if (k == 2) p.b = p.a;                                // equal series
  if (k == 3) std::fill(p.b.begin(), p.b.end(), 0.25);  // constant neighbour
  if (k == 4) std::fill(p.a.begin(), p.a.end(), -1.5);  // constant seed
  if (k == 5) std::fill(p.a.begin(), p.a.end(), 0.0);   // D_max = 0
  if (k == 6 || u(rng) < 0.3)                           // gaps in either series
    for (std::size_t e = 0; e < n; ++e) {
      if (u(rng) < 0.15) p.a[e] = std::numeric_limits<double>::quiet_NaN();
      if (u(rng) < 0.15) p.b[e] = std::numeric_limits<double>::quiet_NaN();
    }
  return p;
}

TEST(Dtw, LowerBoundNeverAboveTheExactCost) {
  std::mt19937_64 rng(17);
  std::vector<double> x, y, rows, columns;
  for (int t = 0; t < 4000; ++t) {
    const Pair p = random_pair(rng);
    full_normalised(p.a, p.b, 0.0, 0.0, 0.0, &x, &y);
    if (x.empty()) continue;
    const double exact = full_cost(x, y);
    const double bound = detail::dtw_lower_bound(x.data(), y.data(), x.size(), rows, columns);
    // Above the exact cost by rounding only (the sums are in another order; a tight bound, as of
    // a constant series, may round up): far inside normalised_dtw's 1e-9 margin.
    const double rounding = 1.0 + 4.0 * double(x.size()) * std::numeric_limits<double>::epsilon();
    ASSERT_LE(bound, exact * rounding) << "trial " << t << ", " << x.size() << " epochs";
    // rows[0] is the bound of every row (what the path pays in rows i.. is at least rows[i]).
    ASSERT_LE(rows[0], bound);
    for (std::size_t i = 0; i + 1 < rows.size(); ++i) ASSERT_GE(rows[i], rows[i + 1]);
  }
}

TEST(Dtw, SameDecisionsAsTheFullMatrix) {
  std::mt19937_64 rng(4);
  const double thresholds[] = {0.1, 0.3, 0.5, 0.9, 1.0};
  int decided_early = 0, exact = 0;
  for (int t = 0; t < 4000; ++t) {
    const Pair p = random_pair(rng);
    const std::size_t n = p.a.size();
    const double norm_a = t % 2 ? 0.0 : p.a[0], norm_b = t % 2 ? 0.0 : p.b[0], origin = t % 3 ? 0.0 : p.a[0];
    const double want = full_normalised(p.a, p.b, norm_a, norm_b, origin);
    for (const double at_least : thresholds) {
      const double got = normalised_dtw(p.a.data(), p.b.data(), n, norm_a, norm_b, origin, at_least);
      if (std::isnan(want)) {
        ASSERT_TRUE(std::isnan(got)) << "trial " << t;
        continue;
      }
      // Below at_least the value is exact, bit for bit; otherwise both are >= at_least.
      if (want < at_least) {
        ASSERT_TRUE(same_bits(got, want)) << "trial " << t << ": " << got << " != " << want;
        ++exact;
      } else {
        ASSERT_GE(got, at_least) << "trial " << t;
        decided_early += got != want;
      }
      // With at_least = 1 the value is exact in every case (it is capped at 1).
      if (at_least == 1.0) {
        ASSERT_TRUE(same_bits(got, want)) << "trial " << t;
      }
    }
  }
  // The test means something: both kinds of result occur.
  EXPECT_GT(decided_early, 100);
  EXPECT_GT(exact, 100);
}

TEST(Dtw, EqualSeriesAreZeroAndLongSeriesMatch) {
  std::mt19937_64 rng(9);
  std::normal_distribution<double> step(0.0, 0.01);
  for (const std::size_t n : {1, 2, 3, 4, 5, 7, 8, 9, 100, 257}) {
    std::vector<double> a(n), b(n);
    double v = 0.0;
    for (std::size_t e = 0; e < n; ++e) v += step(rng), a[e] = v, b[e] = v + step(rng);
    if (n > 1) {
      EXPECT_EQ(normalised_dtw(a.data(), a.data(), n, a[0], a[0], a[0], 0.5), 0.0);
    }
    const double want = full_normalised(a, b, a[0], b[0], 0.0);
    EXPECT_TRUE(same_bits(normalised_dtw(a.data(), b.data(), n, a[0], b[0], 0.0, 1.0), want)) << n << " epochs";
  }
}

TEST(Dtw, ManyPairsAtOnceGiveTheSameBitsAsOneAtATime) {
  // One seed against 0 to 13 neighbours (full groups of lanes and a remainder), lengths from 1
  // epoch to the benchmark's 100, every at_least: each value, stopped (1.0) or exact, equals
  // normalised_dtw's own for that pair.
  std::mt19937_64 rng(23);
  std::normal_distribution<double> step(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int stopped = 0, exact = 0;
  for (const std::size_t n : {1, 2, 3, 4, 5, 7, 9, 60, 100}) {
    for (int trial = 0; trial < 30; ++trial) {
      std::vector<double> a(n);
      double v = 0.0;
      for (double& e : a) e = v += step(rng);
      const std::size_t count = std::size_t(trial % 14);
      std::vector<std::vector<double>> neighbours(count, std::vector<double>(n));
      std::vector<const double*> b;
      std::vector<double> norms;
      for (auto& nb : neighbours) {
        const double kind = u(rng), noise = 2.0 * u(rng);
        double w = 0.0;
        for (std::size_t e = 0; e < n; ++e)
          nb[e] = kind < 0.5 ? a[e] + noise * step(rng) : kind < 0.6 ? a[e] : kind < 0.7 ? 0.25 : w += step(rng);
        b.push_back(nb.data());
        norms.push_back(trial % 2 ? 0.0 : nb[0]);
      }
      const double norm_a = trial % 2 ? 0.0 : a[0], origin = trial % 3 ? 0.0 : a[0];
      for (const double at_least : {0.1, 0.3, 0.5, 0.9, 1.0}) {
        std::vector<double> got(count);
        detail::normalised_dtw_many(a.data(), b.data(), norms.data(), count, n, norm_a, origin, at_least, got.data());
        for (std::size_t k = 0; k < count; ++k) {
          const double want = normalised_dtw(a.data(), b[k], n, norm_a, norms[k], origin, at_least);
          ASSERT_TRUE(same_bits(got[k], want) || (std::isnan(got[k]) && std::isnan(want)))
              << n << " epochs, trial " << trial << ", pair " << k << ": " << got[k] << " != " << want;
          (want == 1.0 && at_least < 1.0 ? stopped : exact) += 1;
        }
      }
    }
  }
  EXPECT_GT(stopped, 100);
  EXPECT_GT(exact, 100);
}

}  // namespace
}  // namespace m3c2::test
