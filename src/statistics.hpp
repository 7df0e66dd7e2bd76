#pragma once
// Central position and spread of a distribution of axial offsets (section 3.1.3).

#include <m3c2/params.hpp>

#include <cstddef>
#include <span>
#include <vector>

namespace m3c2::detail {

struct Spread {
  double centre = 0.0;  ///< i: mean or median
  double sigma = 0.0;   ///< standard deviation, or IQR / kIqrToSigma (a sigma-equivalent)
};

/// Two-pass mean and standard deviation; sigma is NaN for n < 2 with Variance::kSample and for
/// n == 0. The values are summed in the order given.
Spread mean_and_sigma(std::span<const double> values, Variance variance);

/// Median and IQR / kIqrToSigma, quantiles by linear interpolation between order statistics
/// (numpy's default). sigma is NaN for n < 2. `work` is scratch space.
Spread median_and_sigma(std::span<const double> values, std::vector<double>& work);

/// The statistic chosen by `params`.
Spread central_spread(std::span<const double> values, const Params& params, std::vector<double>& work);

/// Quantile q in [0, 1] of sorted values by linear interpolation.
double sorted_quantile(std::span<const double> sorted, double q);

}  // namespace m3c2::detail
