#pragma once
// Standard error of a cylinder's median for eq. (1) (section 3.3, Appendix B): the exact
// bootstrap standard error of the median order statistic, in closed form (Maritz & Jarrett 1978;
// derivation in docs/algorithm.md#6.4).

#include <cstdint>
#include <span>
#include <vector>

namespace m3c2::detail {

/// Weights w_j = P(X*_(m) = x_(j)) of the bootstrap distribution of the m-th order statistic,
/// m = floor(n / 2 + 1 / 2): w_j = I_{j/n}(m, n - m + 1) - I_{(j-1)/n}(m, n - m + 1) (I the
/// regularised incomplete beta function), kept where they exceed 1e-300. Exact (Boost.Math) up to
/// kExactUpTo points; beyond, the normal limit of the Beta(m, n - m + 1) law (its relative error
/// on the standard error is O(1/n), far below the estimate's own sampling error O(n^-1/4)).
/// A pure function of n: the same weights whatever the thread or tile.
struct OrderWeights {
  std::uint32_t first = 0;  ///< index (0-based) of the first kept weight
  std::vector<double> w;
};
OrderWeights median_order_weights(std::uint32_t n);

/// Per-thread cache of median_order_weights() for n <= kExactUpTo.
class MedianWeightCache {
 public:
  static constexpr std::uint32_t kExactUpTo = 1024;
  const OrderWeights& weights(std::uint32_t n);

 private:
  std::vector<OrderWeights> by_n_;
  std::vector<bool> known_;
  OrderWeights large_;  // the last n > kExactUpTo
  std::uint32_t large_n_ = 0;
};

/// sqrt(sum_j w_j (x_(j) - c)^2 - (sum_j w_j (x_(j) - c))^2), c = `centre` (the sample median,
/// about which the sums lose nothing to cancellation). `sorted`: ascending, non-empty.
double median_standard_error(std::span<const double> sorted, double centre, MedianWeightCache& cache);

}  // namespace m3c2::detail
