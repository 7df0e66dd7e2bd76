#include "uncertainty/bootstrap.hpp"

#include "pipeline/statistics.hpp"
#include "support/portable.hpp"

#include <algorithm>
#include <cmath>

namespace m3c2::detail {
namespace {

// SplitMix64 (Steele, Lea & Flood 2014): a tiny generator with a fixed, portable output
// sequence, unlike std::uniform_int_distribution whose algorithm is library-defined.
class SplitMix64 {
 public:
  explicit SplitMix64(std::uint64_t seed) : state_(seed) {}
  std::uint64_t next() {
    std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
  }
  /// Uniform index in [0, n) by multiply-shift (Lemire 2019); bias below 2^-40 for n < 2^24.
  std::size_t below(std::size_t n) { return static_cast<std::size_t>(mul_high(next(), n)); }

 private:
  std::uint64_t state_;
};

/// The median of `v` (reordered), the same bits as sorted_quantile(sorted v, 0.5): the two middle
/// order statistics by selection (O(n)) instead of a sort, interpolated by the same formula.
double selected_median(std::vector<double>& v) {
  const std::size_t n = v.size();
  const double h = (double(n) - 1.0) * 0.5;
  const auto lo = static_cast<std::size_t>(std::floor(h));
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(lo), v.end());
  if (lo + 1 >= n) return v[lo];
  const double upper = *std::min_element(v.begin() + std::ptrdiff_t(lo) + 1, v.end());
  return v[lo] + (h - double(lo)) * (upper - v[lo]);
}

double resampled_stat(std::span<const double> values, const Params& params, SplitMix64& rng, std::vector<double>& draw,
                      std::vector<double>& work) {
  draw.resize(values.size());
  for (double& v : draw) v = values[rng.below(values.size())];
  if (params.statistic == Statistic::kMedian) return selected_median(draw);
  return central_spread(draw, params, work).centre;
}

}  // namespace

double bootstrap_sigma(std::span<const double> t1, std::span<const double> t2, const Params& params,
                       std::uint64_t core_index, std::vector<double>& work, Pulse& pulse) {
  SplitMix64 seeder(params.bootstrap_seed);
  SplitMix64 rng(seeder.next() ^ (core_index * 0xD1B54A32D192ED03ULL));
  std::vector<double> draw, distances(params.bootstrap_samples);
  for (double& d : distances) {
    pulse.beat();
    const double i1 = resampled_stat(t1, params, rng, draw, work);
    const double i2 = resampled_stat(t2, params, rng, draw, work);
    d = i2 - i1;
  }
  return mean_and_sigma(distances, Variance::kSample).sigma;
}

}  // namespace m3c2::detail
