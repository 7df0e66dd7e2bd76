#pragma once
// The rows of normalised_dtw's cumulative cost matrix (src/series/dtw.cpp),
// D[i][j] = |x_i - y_j| + min(D[i-1][j], D[i][j-1], D[i-1][j-1]), a strip of R rows at a time.
//
// Why strips: one row is a chain of dependent additions (each cell needs its left neighbour),
// so the CPU waits on every addition's latency. Within a strip, column j of row r needs only
// column j of row r - 1 and column j - 1 of both, so the R chains of a strip overlap in the
// processor (a wavefront), R cells per latency instead of one. Every cell is the same additions
// of the same values as row by row, and min is exact: the same bits in any order.

#include <cmath>
#include <cstddef>

#if (defined(__SSE2__) || defined(_M_X64)) && !defined(M3C2_PORTABLE_FALLBACKS)
#include <emmintrin.h>
#define M3C2_DTW_SSE2 1
#endif

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

namespace m3c2::detail {

/// dtw_strip() for L pairs at once that share x, each lane l its own y and row (interleaved:
/// y[j * L + l], row[j * L + l], row_min[r * L + l]). Every lane's cells are dtw_strip()'s
/// additions of the same values in the same order: the same bits. Why lanes: the R chains of a
/// strip still wait on each addition's latency; L independent pairs fill that wait, and the
/// compiler computes the lanes of each cell in one vector instruction.
template <std::size_t R, std::size_t L>
inline void dtw_strip_lanes(const double* x, const double* y, std::size_t m, std::size_t i, double* row,
                            double* row_min) {
#if defined(M3C2_DTW_SSE2)
  if constexpr (L == 2) {
    // The same cells with SSE2's two-lane instructions (x86-64's baseline): MINPD(a, b) is
    // a < b ? a : b per lane, so lesser(u, v) is MINPD(v, u); |a| clears the sign bit as std::abs
    // does. The compilers left the generic loops below scalar, where this halves the time per cell.
    const __m128d sign = _mm_set1_pd(-0.0);
    const auto lesser2 = [](__m128d u, __m128d v) { return _mm_min_pd(v, u); };
    const auto cost = [&](__m128d a, __m128d b) { return _mm_andnot_pd(sign, _mm_sub_pd(a, b)); };
    __m128d xi[R], left[R], least[R];
    __m128d up = _mm_loadu_pd(row), top_diagonal = up;
    const __m128d y0 = _mm_loadu_pd(y);
    for (std::size_t r = 0; r < R; ++r) {
      xi[r] = _mm_set1_pd(x[i + r]);
      left[r] = _mm_add_pd(cost(xi[r], y0), up);  // column 0: from above only
      up = left[r];
      least[r] = left[r];
    }
    _mm_storeu_pd(row, left[R - 1]);
    for (std::size_t j = 1; j < m; ++j) {
      const __m128d yj = _mm_loadu_pd(y + 2 * j);
      up = _mm_loadu_pd(row + 2 * j);
      __m128d diagonal = top_diagonal;
      top_diagonal = up;
      for (std::size_t r = 0; r < R; ++r) {
        const __m128d v = _mm_add_pd(cost(xi[r], yj), lesser2(lesser2(up, diagonal), left[r]));
        diagonal = left[r];
        left[r] = v;
        up = v;
        least[r] = lesser2(least[r], v);
      }
      _mm_storeu_pd(row + 2 * j, up);
    }
    for (std::size_t r = 0; r < R; ++r) _mm_storeu_pd(row_min + 2 * r, least[r]);
    return;
  }
#endif
  double xi[R], left[R][L], up[L], top_diagonal[L], diagonal[L], yj[L];
  for (std::size_t l = 0; l < L; ++l) up[l] = top_diagonal[l] = row[l];
  for (std::size_t r = 0; r < R; ++r) {
    xi[r] = x[i + r];
    for (std::size_t l = 0; l < L; ++l) {
      left[r][l] = std::abs(xi[r] - y[l]) + up[l];  // column 0: from above only
      up[l] = left[r][l];
      row_min[r * L + l] = left[r][l];
    }
  }
  for (std::size_t l = 0; l < L; ++l) row[l] = left[R - 1][l];
  for (std::size_t j = 1; j < m; ++j) {
    for (std::size_t l = 0; l < L; ++l) {
      yj[l] = y[j * L + l];
      up[l] = row[j * L + l];
      diagonal[l] = top_diagonal[l];
      top_diagonal[l] = up[l];
    }
    for (std::size_t r = 0; r < R; ++r)
      for (std::size_t l = 0; l < L; ++l) {
        const double v = std::abs(xi[r] - yj[l]) + lesser(lesser(up[l], diagonal[l]), left[r][l]);
        diagonal[l] = left[r][l];
        left[r][l] = v;
        up[l] = v;
        row_min[r * L + l] = lesser(row_min[r * L + l], v);
      }
    for (std::size_t l = 0; l < L; ++l) row[j * L + l] = up[l];
  }
}

}  // namespace m3c2::detail
