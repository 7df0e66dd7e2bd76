#pragma once
// Moving the rows of a point array to new positions in place: how an index orders a cloud's own
// array in key order instead of copying it, and puts it back (octree.hpp, SlotIndex).

#include <algorithm>
#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <utility>

namespace m3c2::detail {

/// Moves row i of xyz (3 doubles) to row dest[i], for every i of [lo, lo + n), where dest holds a
/// permutation of [lo, lo + n); dest is permuted alike (left as the identity). Not by following
/// the permutation's cycles, whose every step is a dependent cache miss on a shuffled cloud
/// (10M points: 1.7 s against 0.24 s for a prefetched gather into a copy), but by an in-place
/// MSD radix pass on the destinations (an American flag sort): they are a permutation, so each
/// of the at most 2048 buckets is known to be the range of its destinations without counting,
/// the bucket heads being filled stay in cache, and a bucket then sorts within itself (10M
/// rows: three levels, the last two within the L2 cache).
inline void move_rows_in_place(double* xyz, std::uint32_t* dest, std::size_t lo, std::size_t n) noexcept {
  if (n < 2) return;
  constexpr int kDigitBits = 11;
  const int shift = std::max(0, int(std::bit_width(n - 1)) - kDigitBits);
  const std::size_t width = std::size_t(1) << shift, buckets = (n + width - 1) / width;
  std::array<std::size_t, std::size_t(1) << kDigitBits> head;
  for (std::size_t b = 0; b < buckets; ++b) head[b] = lo + b * width;
  const auto swap_rows = [&](std::size_t i, std::size_t j) {
    for (int a = 0; a < 3; ++a) std::swap(xyz[3 * i + a], xyz[3 * j + a]);
    std::swap(dest[i], dest[j]);
  };
  for (std::size_t b = 0; b < buckets; ++b) {
    const std::size_t end = std::min(lo + n, lo + (b + 1) * width);
    while (head[b] < end) {
      const std::size_t i = head[b], t = (dest[i] - lo) >> shift;
      if (t == b)
        ++head[b];
      else
        swap_rows(i, head[t]++);  // the row at i is then looked at again
    }
  }
  if (shift == 0) return;  // buckets of one row: every row is in place
  for (std::size_t b = 0; b < buckets; ++b) {
    const std::size_t begin = lo + b * width;
    move_rows_in_place(xyz, dest, begin, std::min(width, lo + n - begin));
  }
}

}  // namespace m3c2::detail
