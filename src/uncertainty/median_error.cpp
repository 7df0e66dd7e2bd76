#include "uncertainty/median_error.hpp"

#include <boost/math/special_functions/beta.hpp>

#include <algorithm>
#include <cmath>

namespace m3c2::detail {
namespace {

constexpr double kSmallest = 1e-300;

/// P(Beta(m, n - m + 1) <= x) = P(Binomial(n, x) >= m), exactly or by its normal limit.
double order_cdf(double x, std::uint32_t n, std::uint32_t m, bool exact) {
  if (x <= 0.0) return 0.0;
  if (x >= 1.0) return 1.0;
  const double a = double(m), b = double(n - m + 1);
  if (exact) return boost::math::ibeta(a, b, x);
  const double mean = a / (a + b), sd = std::sqrt(a * b / ((a + b) * (a + b) * (a + b + 1.0)));
  return 0.5 * std::erfc(-(x - mean) / (sd * std::sqrt(2.0)));
}

}  // namespace

OrderWeights median_order_weights(std::uint32_t n) {
  OrderWeights out;
  if (n == 0) return out;
  const std::uint32_t m = std::max<std::uint32_t>(1, static_cast<std::uint32_t>(std::floor(0.5 * n + 0.5)));
  const bool exact = n <= MedianWeightCache::kExactUpTo;
  std::vector<double> w(n);
  double previous = 0.0;
  for (std::uint32_t j = 1; j <= n; ++j) {
    const double cdf = j == n ? 1.0 : order_cdf(double(j) / double(n), n, m, exact);
    w[j - 1] = std::max(cdf - previous, 0.0);
    previous = cdf;
  }
  std::uint32_t lo = 0, hi = n;
  while (lo < hi && w[lo] <= kSmallest) ++lo;
  while (hi > lo && w[hi - 1] <= kSmallest) --hi;
  out.first = lo;
  out.w.assign(w.begin() + lo, w.begin() + hi);
  return out;
}

const OrderWeights& MedianWeightCache::weights(std::uint32_t n) {
  if (n > kExactUpTo) {
    if (n != large_n_) large_ = median_order_weights(n), large_n_ = n;
    return large_;
  }
  if (by_n_.size() <= n) by_n_.resize(n + 1), known_.resize(n + 1, false);
  if (!known_[n]) by_n_[n] = median_order_weights(n), known_[n] = true;
  return by_n_[n];
}

double median_standard_error(std::span<const double> sorted, double centre, MedianWeightCache& cache) {
  const OrderWeights& ow = cache.weights(static_cast<std::uint32_t>(sorted.size()));
  double s1 = 0.0, s2 = 0.0;
  for (std::size_t j = 0; j < ow.w.size(); ++j) {
    const double v = sorted[ow.first + j] - centre;
    s1 += ow.w[j] * v;
    s2 += ow.w[j] * v * v;
  }
  return std::sqrt(std::max(s2 - s1 * s1, 0.0));
}

}  // namespace m3c2::detail
