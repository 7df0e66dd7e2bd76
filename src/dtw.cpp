// normalised_dtw(): the similarity of two change series in 4D-OBC's region growing (Anders et
// al. 2021, 2.3.2, eq. 3): dynamic time warping with absolute differences, normalised by the
// distance of the seed's series to no change.

#include <m3c2/objects_by_change.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace m3c2 {

double normalised_dtw(const double* a, const double* b, std::size_t n, double norm_a, double norm_b, double dmax_origin,
                      double at_least) {
  double dmax = 0.0;
  for (std::size_t k = 0; k < n; ++k)
    if (!std::isnan(a[k])) dmax += std::abs(a[k] - dmax_origin);
  thread_local std::vector<double> x, y, previous, current;
  x.clear(), y.clear();
  for (std::size_t k = 0; k < n; ++k)
    if (!std::isnan(a[k]) && !std::isnan(b[k])) x.push_back(a[k] - norm_a), y.push_back(b[k] - norm_b);
  const std::size_t m = x.size();
  if (m == 0) return std::numeric_limits<double>::quiet_NaN();
  // Row i of the cumulative cost matrix D[i][j] = |x_i - y_j| + min(D[i-1][j], D[i][j-1], D[i-1][j-1]).
  previous.resize(m), current.resize(m);
  previous[0] = std::abs(x[0] - y[0]);
  for (std::size_t j = 1; j < m; ++j) previous[j] = std::abs(x[0] - y[j]) + previous[j - 1];
  // Early stop: 1 - (dmax - c) / dmax >= at_least once c >= at_least * dmax; the margin keeps the
  // rounding of that expression on the safe side.
  const double stop = at_least < 1.0 ? at_least * dmax * (1.0 + 1e-9) + 1e-300 : INFINITY;
  // Every cost is finite or +inf, never NaN: `lesser` is std::fmin's value without its call
  // (std::fmin was not inlined under the strict floating-point flags: 70 % of 4D-OBC's time).
  const auto lesser = [](double u, double v) { return v < u ? v : u; };
  for (std::size_t i = 1; i < m; ++i) {
    const double xi = x[i];
    double left = std::abs(xi - y[0]) + previous[0];
    current[0] = left;
    double row_min = left, diagonal = previous[0];
    for (std::size_t j = 1; j < m; ++j) {
      const double up = previous[j];
      left = std::abs(xi - y[j]) + lesser(lesser(up, left), diagonal);
      current[j] = left;
      row_min = lesser(row_min, left);
      diagonal = up;
    }
    std::swap(previous, current);
    if (row_min > stop) return 1.0;
  }
  // py4dgeo's form of dtw / D_max, for the same bits at the thresholds.
  return std::fmin(1.0, 1.0 - (dmax - previous[m - 1]) / dmax);
}

}  // namespace m3c2
