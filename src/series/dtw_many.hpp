#pragma once
// normalised_dtw() of one seed's series against many (4D-OBC's region growing compares a seed
// with every neighbour it reaches), kDtwLanes pairs at a time (dtw_rows.hpp, dtw_strip_lanes).

#include <cstddef>

namespace m3c2::detail {

/// Pairs whose cost matrices are computed together: SSE2's two double lanes (x86-64's baseline),
/// the vector path of dtw_strip_lanes; another count takes its generic loops, which the
/// compilers leave scalar (no faster than one pair at a time).
inline constexpr std::size_t kDtwLanes = 2;

/// out[k] = normalised_dtw(a, b[k], n, norm_a, norm_b[k], dmax_origin, at_least) for k < count,
/// the same bits. Neither `a` nor any b[k] may hold a NaN: normalised_dtw leaves out the epochs
/// where either series is NaN, which gives each such pair a length of its own.
void normalised_dtw_many(const double* a, const double* const* b, const double* norm_b, std::size_t count,
                         std::size_t n, double norm_a, double dmax_origin, double at_least, double* out);

}  // namespace m3c2::detail
