#pragma once
// The per-point test of a projection cylinder (section 3.1.3) over one octree leaf: the loop
// where a cylinder query spends most of its time (W6, 2D mode: 54 % of the run). Two points at
// a time in SSE2's two lanes (x86-64's baseline), which give the scalar operations' bits: the
// same IEEE operations in the same order, no fused multiply-add.

#include "index/cylinder.hpp"

#include <cstdint>

#if (defined(__SSE2__) || defined(_M_X64)) && !defined(M3C2_PORTABLE_FALLBACKS)
#include <emmintrin.h>
#define M3C2_CYLINDER_SSE2 1
#endif

namespace m3c2::detail {

/// The test of cylinder.hpp for one point at v = p - core: t = v . n, inside iff t_min <= t <=
/// t_max and |v - t n|^2 <= r2. Writes t to *t_out; returns whether the point is inside.
inline bool cylinder_holds(const double* p, const Cylinder& cyl, double r2, double* t_out) {
  const double vx = p[0] - cyl.core.x(), vy = p[1] - cyl.core.y(), vz = p[2] - cyl.core.z();
  const double t = vx * cyl.normal.x() + vy * cyl.normal.y() + vz * cyl.normal.z();
  const double wx = vx - t * cyl.normal.x(), wy = vy - t * cyl.normal.y(), wz = vz - t * cyl.normal.z();
  *t_out = t;
  return (t >= cyl.t_min) & (t <= cyl.t_max) & (wx * wx + wy * wy + wz * wz <= r2);
}

/// Writes to t_out the offsets t of the points xyz[0, n) (3 doubles each) inside `cyl`, in their
/// order, and to index_out (if not null) original[j] of each point j; returns how many. Both
/// outputs need room for n values: every point is written and the end advanced only past those
/// inside (a branch per point mispredicted: a thin cylinder keeps about a third of a crossing
/// leaf's points).
inline std::uint32_t cylinder_leaf(const double* xyz, std::uint32_t n, const Cylinder& cyl, double r2, double* t_out,
                                   std::uint32_t* index_out, const std::uint32_t* original) {
  std::uint32_t kept = 0, j = 0;
#if defined(M3C2_CYLINDER_SSE2)
  const __m128d cx = _mm_set1_pd(cyl.core.x()), cy = _mm_set1_pd(cyl.core.y()), cz = _mm_set1_pd(cyl.core.z());
  const __m128d nx = _mm_set1_pd(cyl.normal.x()), ny = _mm_set1_pd(cyl.normal.y()), nz = _mm_set1_pd(cyl.normal.z());
  const __m128d lo = _mm_set1_pd(cyl.t_min), hi = _mm_set1_pd(cyl.t_max), radius2 = _mm_set1_pd(r2);
  for (; j + 2 <= n; j += 2) {
    // Points j and j + 1: x0 y0 | z0 x1 | y1 z1, into lanes (x0, x1), (y0, y1), (z0, z1).
    const double* p = xyz + 3 * std::size_t(j);
    const __m128d a = _mm_loadu_pd(p), b = _mm_loadu_pd(p + 2), c = _mm_loadu_pd(p + 4);
    const __m128d vx = _mm_sub_pd(_mm_shuffle_pd(a, b, 2), cx);
    const __m128d vy = _mm_sub_pd(_mm_shuffle_pd(a, c, 1), cy);
    const __m128d vz = _mm_sub_pd(_mm_shuffle_pd(b, c, 2), cz);
    const __m128d t = _mm_add_pd(_mm_add_pd(_mm_mul_pd(vx, nx), _mm_mul_pd(vy, ny)), _mm_mul_pd(vz, nz));
    const __m128d wx = _mm_sub_pd(vx, _mm_mul_pd(t, nx)), wy = _mm_sub_pd(vy, _mm_mul_pd(t, ny)),
                  wz = _mm_sub_pd(vz, _mm_mul_pd(t, nz));
    const __m128d w2 = _mm_add_pd(_mm_add_pd(_mm_mul_pd(wx, wx), _mm_mul_pd(wy, wy)), _mm_mul_pd(wz, wz));
    const __m128d inside = _mm_and_pd(_mm_and_pd(_mm_cmpge_pd(t, lo), _mm_cmple_pd(t, hi)), _mm_cmple_pd(w2, radius2));
    const int mask = _mm_movemask_pd(inside);
    _mm_storel_pd(t_out + kept, t);
    if (index_out) index_out[kept] = original[j];
    kept += mask & 1;
    _mm_storeh_pd(t_out + kept, t);
    if (index_out) index_out[kept] = original[j + 1];
    kept += mask >> 1;
  }
#endif
  for (; j < n; ++j) {
    const bool inside = cylinder_holds(xyz + 3 * std::size_t(j), cyl, r2, t_out + kept);
    if (index_out) index_out[kept] = original[j];
    kept += inside;
  }
  return kept;
}

}  // namespace m3c2::detail
