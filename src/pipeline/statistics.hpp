#pragma once
// Central position and spread of a distribution of axial offsets (section 3.1.3).

#include "uncertainty/median_error.hpp"

#include <m3c2/params.hpp>

#include <cstddef>
#include <span>
#include <vector>

namespace m3c2::detail {

struct Spread {
  double centre = 0.0;  ///< i: mean or median
  double sigma = 0.0;   ///< standard deviation, or IQR / kIqrToSigma (a sigma-equivalent)
  double se = 0.0;      ///< standard error of the centre, what eq. (1) sums (centre_spread)
};

/// Two-pass mean and standard deviation; sigma is NaN for n < 2 with Variance::kSample and for
/// n == 0. Each pass sums value j into partial sum j mod 4, then (s0 + s1) + (s2 + s3): an order
/// fixed by the values' order (key order in a cylinder, the same in any tile), four additions in
/// flight instead of one chain (a cylinder's statistics were 10 % of a 2D-mode run).
Spread mean_and_sigma(std::span<const double> values, Variance variance);

/// Median and IQR / kIqrToSigma, quantiles by linear interpolation between order statistics
/// (numpy's default). sigma is NaN for n < 2. `work` is scratch space.
Spread median_and_sigma(std::span<const double> values, std::vector<double>& work);

/// The statistic chosen by `params`, with the standard error of its centre: sigma / sqrt(n) for
/// the mean (and the median with MedianLod::kCloudCompare), the Maritz-Jarrett standard error for
/// the median otherwise (NaN when no `weights` cache is given: a bootstrap resample needs none).
Spread central_spread(std::span<const double> values, const Params& params, std::vector<double>& work,
                      MedianWeightCache* weights = nullptr);

/// Quantile q in [0, 1] of sorted values by linear interpolation.
double sorted_quantile(std::span<const double> sorted, double q);

}  // namespace m3c2::detail
