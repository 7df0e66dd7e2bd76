#pragma once
// The tests' DTW oracle: the plain full cost matrix of Anders et al. 2021, eq. 3 (absolute
// differences, steps (1,0), (0,1), (1,1)), O(m^2), for series of equal length m >= 1.

#include <cmath>
#include <cstddef>
#include <vector>

namespace m3c2::test {

/// The DTW cost of the full (m x m) matrix, row by row, with std::fmin.
inline double full_dtw_cost(const std::vector<double>& x, const std::vector<double>& y) {
  const std::size_t m = x.size();
  std::vector<double> D(m * m);
  for (std::size_t i = 0; i < m; ++i)
    for (std::size_t j = 0; j < m; ++j) {
      double best = 0.0;
      if (i > 0 && j > 0)
        best = std::fmin(std::fmin(D[(i - 1) * m + j], D[i * m + j - 1]), D[(i - 1) * m + j - 1]);
      else if (i > 0)
        best = D[(i - 1) * m + j];
      else if (j > 0)
        best = D[j - 1];
      D[i * m + j] = std::abs(x[i] - y[j]) + best;
    }
  return D[m * m - 1];
}

}  // namespace m3c2::test
