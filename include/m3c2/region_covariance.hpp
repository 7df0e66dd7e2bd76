#pragma once
// The double sum S = sum_i sum_j C(|x_i - x_j|) of a spatially correlated error model's
// covariance over the points of a region: the correlated part of the variance of a regional mean,
// Var(mean) = (sum_i u_i^2 + S) / N^2 (`m3c2 aggregate`, docs/algorithm.md "Aggregates over a
// region"; Rolstad et al. 2009). C is the covariance of the model's CORRELATED components (the
// nugget excluded; it is the u_i^2 part), in plan view (x, y).
//
// Exactly it is O(N^2): region_covariance_sum bins the points, per component, into square bins of
// side `bin_fraction` x range, and sums
//   - within a bin, and between two touching bins (the 8 around it): every pair exactly,
//   - between two farther bins: count_a x count_b x the mean of C over their pairs to second
//     order about the centroids' distance h (the delta method, from each bin's point covariance:
//     C(h) + (C''(h) s_par + C'(h) s_perp / h) / 2),
// over the bin pairs closer than the component's reach (its range for the spherical, which is 0
// beyond; `exponential_reach` practical ranges for the exponential, whose dropped tail is a
// share of at most (1 + 3k) e^{-3k} of the sum over a uniform density: 8e-5 at k = 4).
// tests/cpp/test_region_covariance.cpp checks it against region_covariance_exact.

#include <m3c2/run_options.hpp>

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace m3c2 {

enum class CovarianceKind : std::uint8_t {
  kSpherical = 0,    ///< C(h) = sill (1 - 1.5 h/r + 0.5 (h/r)^3) for h < r, 0 beyond
  kExponential = 1,  ///< C(h) = sill exp(-3 h / r), r the practical range (95 % of the sill)
};

struct CovarianceComponent {
  CovarianceKind kind = CovarianceKind::kSpherical;
  double sill = 0;   ///< partial sill (a variance), >= 0
  double range = 1;  ///< > 0
};

struct CovarianceSumOptions {
  double bin_fraction = 0.125;     ///< bin side / the component's range, in (0, 1]
  double exponential_reach = 4.0;  ///< the exponential's cut-off, in practical ranges, >= 1
  /// the most bins one component's grid over the points' bounding box may have: beyond, the bins
  /// are made larger (reported in CovarianceSum::bin_side)
  std::uint64_t max_bins = std::uint64_t(1) << 24;  // 64 MiB of bin lookup
};

struct CovarianceSum {
  double sum = 0;                ///< S, over every ordered pair (i, j), i == j included
  std::vector<double> bin_side;  ///< the bin side each component used
};

/// The covariance of one component at lag h: the one place of the models' formulas (the Python
/// error model's Component.covariance and .variogram call these through the binding).
double component_covariance(const CovarianceComponent& c, double h);

/// Its semivariance gamma(h) = sill - C(h), written so that it keeps its digits near h = 0
/// (sill (1.5 r - 0.5 r^3); -sill expm1(-3 r)), where the variogram is fitted.
double component_variogram(const CovarianceComponent& c, double h);

/// S over the points `xy` (x0, y0, x1, y1, ...: 2 N finite values) by bins (above). The same bits
/// for any thread count. Throws InvalidArgument on bad inputs.
CovarianceSum region_covariance_sum(std::span<const double> xy, std::span<const CovarianceComponent> components,
                                    const CovarianceSumOptions& options = {}, const RunOptions& run = {});

/// S by the exact O(N^2) sum (tests, small regions). The same bits for any thread count.
double region_covariance_exact(std::span<const double> xy, std::span<const CovarianceComponent> components,
                               const RunOptions& run = {});

}  // namespace m3c2
