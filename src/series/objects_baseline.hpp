#pragma once
// The baseline of 4D-OBC's default rule (ObjectsDtw::kBaseline, include/m3c2/objects_by_change.hpp):
// the level of a series before a change, the median of its epochs [base, start].
//
// Why the median of a window and not one epoch: the change-point detection fitted each segment
// with the L1 cost, whose optimum is the segment's median (Truong et al. 2020, cost "l1"; Anders
// et al. 2021, 2.3.1); the half window before the change point is the segment the detector saw
// the series leave. One epoch carries the full per-epoch noise, and the seed's first epoch after a
// step is already the new level, so a step measured from it looks like no change.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <vector>

namespace m3c2::detail {

/// Median of row[first..last] (inclusive), NaN ignored (the mean of the two middle values of an
/// even count, as numpy's); NaN when every value is NaN. The baseline is nan_median(row, base, start).
inline double nan_median(const double* row, std::size_t first, std::size_t last) {
  thread_local std::vector<double> v;
  v.clear();
  for (std::size_t k = first; k <= last; ++k)
    if (!std::isnan(row[k])) v.push_back(row[k]);
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const std::size_t h = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(h), v.end());
  if (v.size() % 2 == 1) return v[h];
  return (*std::max_element(v.begin(), v.begin() + std::ptrdiff_t(h)) + v[h]) / 2.0;
}

}  // namespace m3c2::detail
