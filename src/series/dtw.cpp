// normalised_dtw(): the similarity of two change series in 4D-OBC's region growing (Anders et
// al. 2021, 2.3.2, eq. 3): dynamic time warping with absolute differences, normalised by the
// distance of the seed's series to no change.

#include <m3c2/objects_by_change.hpp>

#include "series/dtw_bound.hpp"
#include "series/dtw_many.hpp"
#include "series/dtw_rows.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

namespace m3c2 {
namespace {

/// D_max of eq. 3: the distance of the seed's series to no change (its NaN epochs left out).
double dmax_of(const double* a, std::size_t n, double dmax_origin) {
  double dmax = 0.0;
  for (std::size_t k = 0; k < n; ++k)
    if (!std::isnan(a[k])) dmax += std::abs(a[k] - dmax_origin);
  return dmax;
}

/// Early stop: 1 - (dmax - c) / dmax >= at_least once c >= at_least * dmax; the margin keeps the
/// rounding of that expression on the safe side. With at_least >= 1 the 1 returned is the exact
/// value (the result is capped at 1), so the seed scores may stop too.
double stop_cost(double at_least, double dmax) { return std::min(at_least, 1.0) * dmax * (1.0 + 1e-9) + 1e-300; }

/// py4dgeo's form of dtw / D_max, for the same bits at the thresholds.
double normalised(double dmax, double cost) { return std::fmin(1.0, 1.0 - (dmax - cost) / dmax); }

constexpr std::size_t kStrip = 4;  // rows of the matrix a strip at a time (dtw_rows.hpp)

}  // namespace

double normalised_dtw(const double* a, const double* b, std::size_t n, double norm_a, double norm_b, double dmax_origin,
                      double at_least) {
  const double dmax = dmax_of(a, n, dmax_origin);
  thread_local std::vector<double> x, y;
  x.clear(), y.clear();
  for (std::size_t k = 0; k < n; ++k)
    if (!std::isnan(a[k]) && !std::isnan(b[k])) x.push_back(a[k] - norm_a), y.push_back(b[k] - norm_b);
  const std::size_t m = x.size();
  if (m == 0) return std::numeric_limits<double>::quiet_NaN();
  const double stop = stop_cost(at_least, dmax);
  // A lower bound on the cost first (src/series/dtw_bound.hpp), O(m): it decides the pairs far from
  // each other without the O(m^2) matrix (6 % of the DTWs of bench/series_py4dgeo.py at 100k
  // points). rest[i + 1] also bounds what the path still pays below row i, so the stop after
  // each row may come rows earlier.
  thread_local std::vector<double> rest, columns;
  detail::dtw_row_bounds(x.data(), y.data(), m, rest);
  if (rest[0] > stop) return 1.0;
  detail::dtw_row_bounds(y.data(), x.data(), m, columns);
  if (columns[0] > stop) return 1.0;
  // The matrix, a strip of rows at a time (src/series/dtw_rows.hpp); after each strip, the path leaves
  // each of its rows at a cost >= that row's minimum and pays at least rest[i + 1] below it.
  thread_local std::vector<double> row;
  row.resize(m);
  row[0] = std::abs(x[0] - y[0]);
  for (std::size_t j = 1; j < m; ++j) row[j] = std::abs(x[0] - y[j]) + row[j - 1];
  double row_min[kStrip];
  for (std::size_t i = 1; i < m;) {
    const std::size_t h = m - i >= kStrip ? kStrip : 1;
    if (h == kStrip)
      detail::dtw_strip<kStrip>(x.data(), y.data(), m, i, row.data(), row_min);
    else
      detail::dtw_strip<1>(x.data(), y.data(), m, i, row.data(), row_min);
    for (std::size_t r = 0; r < h; ++r)
      if (row_min[r] + rest[i + r + 1] > stop) return 1.0;
    i += h;
  }
  return normalised(dmax, row[m - 1]);
}

namespace detail {

void normalised_dtw_many(const double* a, const double* const* b, const double* norm_b, std::size_t count,
                         std::size_t n, double norm_a, double dmax_origin, double at_least, double* out) {
  constexpr std::size_t L = kDtwLanes;
  std::size_t k = 0;
  if (n > 0) {
    // normalised_dtw()'s steps for L pairs, each lane stopped (1.0) where that pair's would be.
    const double dmax = dmax_of(a, n, dmax_origin), stop = stop_cost(at_least, dmax);
    thread_local std::vector<double> x, y, one, columns, row;
    thread_local std::array<std::vector<double>, L> rest;
    x.resize(n), y.resize(n * L), one.resize(n), row.resize(n * L);
    for (std::size_t j = 0; j < n; ++j) x[j] = a[j] - norm_a;
    for (; k + L <= count; k += L) {
      bool live[L];
      std::size_t alive = 0;
      for (std::size_t l = 0; l < L; ++l) {
        for (std::size_t j = 0; j < n; ++j) y[j * L + l] = one[j] = b[k + l][j] - norm_b[k + l];
        dtw_row_bounds(x.data(), one.data(), n, rest[l]);
        live[l] = !(rest[l][0] > stop);
        if (live[l]) {
          dtw_row_bounds(one.data(), x.data(), n, columns);
          live[l] = !(columns[0] > stop);
        }
        alive += live[l];
        out[k + l] = 1.0;
      }
      if (alive == 0) continue;
      for (std::size_t l = 0; l < L; ++l) row[l] = std::abs(x[0] - y[l]);
      for (std::size_t j = 1; j < n; ++j)
        for (std::size_t l = 0; l < L; ++l) row[j * L + l] = std::abs(x[0] - y[j * L + l]) + row[(j - 1) * L + l];
      double row_min[kStrip * L];
      for (std::size_t i = 1; i < n && alive > 0;) {
        const std::size_t h = n - i >= kStrip ? kStrip : 1;
        if (h == kStrip)
          dtw_strip_lanes<kStrip, L>(x.data(), y.data(), n, i, row.data(), row_min);
        else
          dtw_strip_lanes<1, L>(x.data(), y.data(), n, i, row.data(), row_min);
        for (std::size_t r = 0; r < h; ++r)
          for (std::size_t l = 0; l < L; ++l)
            if (live[l] && row_min[r * L + l] + rest[l][i + r + 1] > stop) live[l] = false, --alive;
        i += h;
      }
      for (std::size_t l = 0; l < L; ++l)
        if (live[l]) out[k + l] = normalised(dmax, row[(n - 1) * L + l]);
    }
  }
  for (; k < count; ++k) out[k] = normalised_dtw(a, b[k], n, norm_a, norm_b[k], dmax_origin, at_least);
}

}  // namespace detail

}  // namespace m3c2
