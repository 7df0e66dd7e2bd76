// normalised_dtw(): the similarity of two change series in 4D-OBC's region growing (Anders et
// al. 2021, 2.3.2, eq. 3): dynamic time warping with absolute differences, normalised by the
// distance of the seed's series to no change.

#include <m3c2/objects_by_change.hpp>

#include "dtw_bound.hpp"
#include "dtw_rows.hpp"

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
  thread_local std::vector<double> x, y;
  x.clear(), y.clear();
  for (std::size_t k = 0; k < n; ++k)
    if (!std::isnan(a[k]) && !std::isnan(b[k])) x.push_back(a[k] - norm_a), y.push_back(b[k] - norm_b);
  const std::size_t m = x.size();
  if (m == 0) return std::numeric_limits<double>::quiet_NaN();
  // Early stop: 1 - (dmax - c) / dmax >= at_least once c >= at_least * dmax; the margin keeps the
  // rounding of that expression on the safe side. With at_least >= 1 the 1 returned is the exact
  // value (the result is capped at 1), so the seed scores may stop too.
  const double stop = std::min(at_least, 1.0) * dmax * (1.0 + 1e-9) + 1e-300;
  // A lower bound on the cost first (src/dtw_bound.hpp), O(m): it decides the pairs far from
  // each other without the O(m^2) matrix (6 % of the DTWs of bench/series_py4dgeo.py at 100k
  // points). rest[i + 1] also bounds what the path still pays below row i, so the stop after
  // each row may come rows earlier.
  thread_local std::vector<double> rest, columns;
  detail::dtw_row_bounds(x.data(), y.data(), m, rest);
  if (rest[0] > stop) return 1.0;
  detail::dtw_row_bounds(y.data(), x.data(), m, columns);
  if (columns[0] > stop) return 1.0;
  // The matrix, a strip of rows at a time (src/dtw_rows.hpp); after each strip, the path leaves
  // each of its rows at a cost >= that row's minimum and pays at least rest[i + 1] below it.
  thread_local std::vector<double> row;
  row.resize(m);
  row[0] = std::abs(x[0] - y[0]);
  for (std::size_t j = 1; j < m; ++j) row[j] = std::abs(x[0] - y[j]) + row[j - 1];
  constexpr std::size_t strip = 4;
  double row_min[strip];
  for (std::size_t i = 1; i < m;) {
    const std::size_t h = m - i >= strip ? strip : 1;
    if (h == strip)
      detail::dtw_strip<strip>(x.data(), y.data(), m, i, row.data(), row_min);
    else
      detail::dtw_strip<1>(x.data(), y.data(), m, i, row.data(), row_min);
    for (std::size_t r = 0; r < h; ++r)
      if (row_min[r] + rest[i + r + 1] > stop) return 1.0;
    i += h;
  }
  // py4dgeo's form of dtw / D_max, for the same bits at the thresholds.
  return std::fmin(1.0, 1.0 - (dmax - row[m - 1]) / dmax);
}

}  // namespace m3c2
