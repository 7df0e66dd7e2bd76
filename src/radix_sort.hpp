#pragma once
// The octree's sort (octree.cpp): Morton keys and their points' original indices sorted
// together, in place, by key and, among equal keys, by index: from an ascending order, the
// order a stable sort gives. Any thread count gives that one order, since it is a total order
// on (key, index) pairs.

#include "parallel_for.hpp"
#include "portable.hpp"

#include <m3c2/run_options.hpp>

#include <algorithm>
#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <utility>

namespace m3c2::detail {

inline int highest_bit(std::uint64_t x) { return 63 - std::countl_zero(x); }
inline int highest_bit(Uint128 x) {
  const std::uint64_t hi = high64(x);
  return hi ? 127 - std::countl_zero(hi) : highest_bit(std::uint64_t(x));
}

/// Whether key a sorts before key b.
inline bool key_less(std::uint64_t a, std::uint64_t b) { return a < b; }
inline bool key_less(Uint128 a, Uint128 b) {
  return high64(a) != high64(b) ? high64(a) < high64(b) : std::uint64_t(a) < std::uint64_t(b);
}

namespace radix {

constexpr int kMaxDigitBits = 11;
constexpr std::size_t kInsertionSort = 32;  // ranges up to this size are sorted by insertion
// Below this size a range is sorted on the calling thread alone: sharing it costs more.
constexpr std::size_t kParallelSort = std::size_t(1) << 16;

/// The bucket starts of one digit: start[b] .. start[b + 1] for bucket b < buckets.
struct Buckets {
  std::array<std::size_t, (1u << kMaxDigitBits) + 1> start;
  std::size_t buckets = 0;
};

/// Sorts a range of at most kInsertionSort keys, or of one key, and returns true; otherwise
/// returns false and sets `diff` to the bits in which its keys differ.
template <class K>
bool sort_small(K* keys, std::uint32_t* order, std::size_t n, K& diff) {
  if (n <= kInsertionSort) {
    const auto before = [&](std::size_t i, std::size_t j) {
      return key_less(keys[i], keys[j]) || (keys[i] == keys[j] && order[i] < order[j]);
    };
    for (std::size_t i = 1; i < n; ++i)
      for (std::size_t j = i; j > 0 && before(j, j - 1); --j)
        std::swap(keys[j], keys[j - 1]), std::swap(order[j], order[j - 1]);
    return true;
  }
  diff = 0;
  for (std::size_t i = 1; i < n; ++i) diff |= keys[i] ^ keys[0];
  if (diff == K(0)) {  // one key
    std::sort(order, order + n);
    return true;
  }
  return false;
}

/// One pass of an in-place MSD radix sort (American flag) on the highest digit that varies
/// within the range (`diff`: the bits that do): each key moved into its digit's bucket. The
/// digit is narrower for a small range, about a quarter as many buckets as keys.
template <class K>
void split_by_digit(K* keys, std::uint32_t* order, std::size_t n, K diff, Buckets& out) {
  const int width = std::clamp(int(std::bit_width(n)) - 2, 1, kMaxDigitBits);
  const int bits = highest_bit(diff) + 1, shift = std::max(0, bits - width);
  const std::uint64_t mask = (std::uint64_t(1) << (bits - shift)) - 1;
  const auto digit = [&](K key) { return std::size_t(std::uint64_t(key >> shift) & mask); };
  const std::size_t buckets = std::size_t(mask) + 1;
  auto& start = out.start;
  std::fill(start.begin(), start.begin() + buckets + 1, std::size_t(0));
  for (std::size_t i = 0; i < n; ++i) ++start[1 + digit(keys[i])];
  for (std::size_t b = 0; b < buckets; ++b) start[b + 1] += start[b];
  std::array<std::size_t, 1u << kMaxDigitBits> head;
  std::copy(start.begin(), start.begin() + buckets, head.begin());
  // Each key out of place starts a cycle: held, it displaces the key at its bucket's head, which
  // is held in turn, until one belongs where the cycle started (one read and one write per key
  // moved, where swapping through the start also wrote and read it there).
  for (std::size_t b = 0; b < buckets; ++b)
    while (head[b] < start[b + 1]) {
      K key = keys[head[b]];
      std::uint32_t index = order[head[b]];
      for (std::size_t d = digit(key); d != b; d = digit(key)) {
        const std::size_t j = head[d]++;
        std::swap(key, keys[j]), std::swap(index, order[j]);
      }
      keys[head[b]] = key, order[head[b]] = index;
      ++head[b];
    }
  out.buckets = buckets;
}

template <class K>
void sort_range(K* keys, std::uint32_t* order, std::size_t n) {
  K diff;
  if (sort_small(keys, order, n, diff)) return;
  Buckets b;
  split_by_digit(keys, order, n, diff, b);
  for (std::size_t k = 0; k < b.buckets; ++k)
    sort_range(keys + b.start[k], order + b.start[k], b.start[k + 1] - b.start[k]);
}

}  // namespace radix

/// Sorts keys[0, n) and order alike by key, ties by order, without buffers (docs/performance.md,
/// memory: a stable LSD radix sort of 126-bit keys with its second key and order arrays was the
/// build's peak): an in-place MSD radix sort from the highest bit that varies within each range
/// (a cloud straddling a coordinate plane through the grid's origin varies in every bit above
/// its cells, each side of it in a few only), each bucket sorted alike; small ranges by
/// insertion, a range of one key by order alone. On run's threads: the first digit's pass on
/// the calling thread, then its buckets shared among the threads (parallel_for.hpp), each
/// sorted serially; the same result. (A parallel first pass, counting and scattering the points
/// by digit and computing their keys again in that order, was slower on one thread and on two:
/// the keys' random reads of the points cost more than the in-place moves.)
template <class K>
void sort_in_place(K* keys, std::uint32_t* order, std::size_t n, const RunOptions& run) {
  K diff;
  if (n < radix::kParallelSort || requested_threads(run) < 2) return radix::sort_range(keys, order, n);
  if (radix::sort_small(keys, order, n, diff)) return;
  radix::Buckets b;
  radix::split_by_digit(keys, order, n, diff, b);
  parallel_blocks<int>(
      b.buckets, run,
      [&](std::size_t begin, std::size_t end, int&) {
        for (std::size_t k = begin; k < end; ++k)
          radix::sort_range(keys + b.start[k], order + b.start[k], b.start[k + 1] - b.start[k]);
      },
      1);
}

}  // namespace m3c2::detail
