#pragma once
// The rows of normalised_dtw's cumulative cost matrix (src/dtw.cpp),
// D[i][j] = |x_i - y_j| + min(D[i-1][j], D[i][j-1], D[i-1][j-1]), a strip of R rows at a time.
//
// Why strips: one row is a chain of dependent additions (each cell needs its left neighbour),
// so the CPU waits on every addition's latency. Within a strip, column j of row r needs only
// column j of row r - 1 and column j - 1 of both, so the R chains of a strip overlap in the
// processor (a wavefront), R cells per latency instead of one. Every cell is the same additions
// of the same values as row by row, and min is exact: the same bits in any order.

#include <cmath>
#include <cstddef>

namespace m3c2::detail {

/// The costs are finite or +inf, never NaN: std::fmin's value without its call (it was not
/// inlined under the strict floating-point flags: 70 % of 4D-OBC's time then).
inline double lesser(double u, double v) { return v < u ? v : u; }

/// Rows i..i+R-1 of the matrix: `row` holds row i - 1 on entry and row i + R - 1 on return;
/// row_min[r] is the least cost of row i + r.
template <std::size_t R>
inline void dtw_strip(const double* x, const double* y, std::size_t m, std::size_t i, double* row, double* row_min) {
  double xi[R], left[R];
  double up = row[0];
  for (std::size_t r = 0; r < R; ++r) {
    xi[r] = x[i + r];
    left[r] = std::abs(xi[r] - y[0]) + up;  // column 0: from above only
    up = left[r];
    row_min[r] = left[r];
  }
  double top_diagonal = row[0];  // D[i-1][j-1]
  row[0] = left[R - 1];
  for (std::size_t j = 1; j < m; ++j) {
    const double yj = y[j];
    up = row[j];
    double diagonal = top_diagonal;
    top_diagonal = up;
    for (std::size_t r = 0; r < R; ++r) {
      // min(up, diagonal) first: only the left neighbour is on the chain of this row.
      const double v = std::abs(xi[r] - yj) + lesser(lesser(up, diagonal), left[r]);
      diagonal = left[r];  // D[i+r][j-1], the diagonal of row r + 1
      left[r] = v;
      up = v;
      row_min[r] = lesser(row_min[r], v);
    }
    row[j] = up;
  }
}

}  // namespace m3c2::detail
