#include "pipeline/statistics.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace m3c2::detail {
namespace {
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// sum of term(v) over values, in four interleaved partial sums (mean_and_sigma's order).
template <class Term>
double sum_in_four(std::span<const double> values, Term&& term) {
  std::array<double, 4> s{};
  const std::size_t n = values.size();
  std::size_t j = 0;
  for (; j + 4 <= n; j += 4)
    for (std::size_t k = 0; k < 4; ++k) s[k] += term(values[j + k]);
  for (std::size_t k = 0; j < n; ++j, ++k) s[k] += term(values[j]);
  return (s[0] + s[1]) + (s[2] + s[3]);
}

}  // namespace

Spread mean_and_sigma(std::span<const double> values, Variance variance) {
  const std::size_t n = values.size();
  if (n == 0) return {kNaN, kNaN};
  const double mean = sum_in_four(values, [](double v) { return v; }) / double(n);
  const double ss = sum_in_four(values, [mean](double v) { return (v - mean) * (v - mean); });
  const double denom = variance == Variance::kSample ? double(n) - 1.0 : double(n);
  const double sigma = denom > 0.0 ? std::sqrt(ss / denom) : kNaN;
  return {mean, sigma};
}

double sorted_quantile(std::span<const double> sorted, double q) {
  const double h = (double(sorted.size()) - 1.0) * q;
  const auto lo = static_cast<std::size_t>(std::floor(h));
  if (lo + 1 >= sorted.size()) return sorted[sorted.size() - 1];
  return sorted[lo] + (h - double(lo)) * (sorted[lo + 1] - sorted[lo]);
}

Spread median_and_sigma(std::span<const double> values, std::vector<double>& work) {
  if (values.empty()) return {kNaN, kNaN};
  work.assign(values.begin(), values.end());
  std::sort(work.begin(), work.end());
  const double median = sorted_quantile(work, 0.5);
  if (work.size() < 2) return {median, kNaN};
  const double iqr = sorted_quantile(work, 0.75) - sorted_quantile(work, 0.25);
  return {median, iqr / kIqrToSigma};
}

Spread central_spread(std::span<const double> values, const Params& params, std::vector<double>& work,
                      MedianWeightCache* weights) {
  const double root_n = std::sqrt(double(values.size()));
  if (params.statistic != Statistic::kMedian) {
    Spread s = mean_and_sigma(values, params.variance);
    s.se = s.sigma / root_n;
    return s;
  }
  Spread s = median_and_sigma(values, work);  // leaves `work` sorted
  if (params.median_lod == MedianLod::kCloudCompare)
    s.se = s.sigma / root_n;
  else
    s.se = weights && !values.empty() ? median_standard_error(work, s.centre, *weights) : kNaN;
  return s;
}

}  // namespace m3c2::detail
