#pragma once
// The octree's sort (octree.cpp): Morton keys and their points' original indices sorted
// together, in place, by key and, among equal keys, by index: from an ascending order, the
// order a stable sort gives. Any thread count gives that one order, since it is a total order
// on (key, index) pairs.

#include "support/parallel_for.hpp"
#include "support/portable.hpp"

#include <m3c2/run_options.hpp>

#include <algorithm>
#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

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
// Ranges up to this size whose keys vary in at most kLsdPasses digits are sorted by LSD passes
// through a buffer of their size (sort_by_digits); larger ones split by their highest digit.
constexpr std::size_t kLsdSort = 4096;
constexpr int kLsdPasses = 5;
constexpr std::size_t kShortTies = 16;  // runs of equal keys up to this long: by insertion
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

/// A range's buffers for sort_by_digits (at most kLsdSort values each), one per thread.
template <class K>
struct Scratch {
  std::vector<K> keys;
  std::vector<std::uint32_t> order;
  std::vector<std::uint32_t> count;
};

inline int lowest_bit(std::uint64_t x) { return std::countr_zero(x); }
inline int lowest_bit(Uint128 x) {
  const std::uint64_t lo = std::uint64_t(x);
  return lo ? std::countr_zero(lo) : 64 + std::countr_zero(high64(x));
}

/// Sorts a range of at most kLsdSort keys varying in the bits `diff` by key, ties by order, and
/// returns true; returns false (nothing moved) when those bits span more than kLsdPasses digits.
/// Stable LSD passes from the lowest varying bit, through `scratch`, then each run of equal keys
/// sorted by order: the in-place split's cycles leave a range's ties in no particular order, and
/// its recursion into buckets of about four keys cost 30 ns a key (the sort was 38 % of a
/// 1M-point index build), against about 15 here.
template <class K>
bool sort_by_digits(K* keys, std::uint32_t* order, std::size_t n, K diff, Scratch<K>& scratch) {
  const int lowest = lowest_bit(diff), bits = highest_bit(diff) + 1 - lowest;
  const int widest = std::clamp(int(std::bit_width(n)) - 1, 4, kMaxDigitBits);
  const int passes = (bits + widest - 1) / widest;
  if (passes > kLsdPasses) return false;
  const int width = (bits + passes - 1) / passes;
  const std::size_t buckets = std::size_t(1) << width;
  scratch.keys.resize(n), scratch.order.resize(n), scratch.count.resize(buckets + 1);
  K *from_keys = keys, *to_keys = scratch.keys.data();
  std::uint32_t *from_order = order, *to_order = scratch.order.data();
  std::uint32_t* count = scratch.count.data();
  for (int pass = 0; pass < passes; ++pass) {
    const int shift = lowest + pass * width;
    const auto digit = [&](K key) { return std::size_t(std::uint64_t(key >> shift) & (buckets - 1)); };
    std::fill(count, count + buckets + 1, 0u);
    for (std::size_t i = 0; i < n; ++i) ++count[1 + digit(from_keys[i])];
    for (std::size_t b = 0; b < buckets; ++b) count[b + 1] += count[b];
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t j = count[digit(from_keys[i])]++;
      to_keys[j] = from_keys[i], to_order[j] = from_order[i];
    }
    std::swap(from_keys, to_keys), std::swap(from_order, to_order);
  }
  if (from_keys != keys) std::copy(from_keys, from_keys + n, keys), std::copy(from_order, from_order + n, order);
  for (std::size_t begin = 0, end = 1; begin < n; begin = end++) {
    while (end < n && keys[end] == keys[begin]) ++end;
    if (end - begin > kShortTies) {
      std::sort(order + begin, order + end);
      continue;
    }
    for (std::size_t i = begin + 1; i < end; ++i)
      for (std::size_t j = i; j > begin && order[j] < order[j - 1]; --j) std::swap(order[j], order[j - 1]);
  }
  return true;
}

template <class K>
void sort_range(K* keys, std::uint32_t* order, std::size_t n, Scratch<K>& scratch) {
  K diff;
  if (sort_small(keys, order, n, diff)) return;
  if (n <= kLsdSort && sort_by_digits(keys, order, n, diff, scratch)) return;
  Buckets b;
  split_by_digit(keys, order, n, diff, b);
  for (std::size_t k = 0; k < b.buckets; ++k)
    sort_range(keys + b.start[k], order + b.start[k], b.start[k + 1] - b.start[k], scratch);
}

}  // namespace radix

/// Sorts keys[0, n) and order alike by key, ties by order, without buffers (docs/performance.md,
/// memory: a stable LSD radix sort of 126-bit keys with its second key and order arrays was the
/// build's peak): an in-place MSD radix sort from the highest bit that varies within each range
/// (a cloud straddling a coordinate plane through the grid's origin varies in every bit above
/// its cells, each side of it in a few only), each bucket sorted alike; ranges of a few thousand
/// keys by LSD passes through a buffer of their size (sort_by_digits), the smallest by insertion,
/// a range of one key by order alone. On run's threads: the first digit's pass on
/// the calling thread, then its buckets shared among the threads (parallel_for.hpp), each
/// sorted serially; the same result. (A parallel first pass, counting and scattering the points
/// by digit and computing their keys again in that order, was slower on one thread and on two:
/// the keys' random reads of the points cost more than the in-place moves.)
template <class K>
void sort_in_place(K* keys, std::uint32_t* order, std::size_t n, const RunOptions& run) {
  K diff;
  if (n < radix::kParallelSort || requested_threads(run) < 2) {
    radix::Scratch<K> scratch;
    return radix::sort_range(keys, order, n, scratch);
  }
  if (radix::sort_small(keys, order, n, diff)) return;
  radix::Buckets b;
  radix::split_by_digit(keys, order, n, diff, b);
  parallel_blocks<radix::Scratch<K>>(
      b.buckets, run,
      [&](std::size_t begin, std::size_t end, radix::Scratch<K>& scratch) {
        for (std::size_t k = begin; k < end; ++k)
          radix::sort_range(keys + b.start[k], order + b.start[k], b.start[k + 1] - b.start[k], scratch);
      },
      1);
}

}  // namespace m3c2::detail
