#include "index/spatial_order.hpp"

#include "index/morton.hpp"

#include <m3c2/errors.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>
#include <utility>

namespace m3c2::detail {
namespace {

// A core point's Morton key (10 bits per axis, 1024 cells: finer buys no locality, only passes)
// and its index share one 64-bit word, key above: sorting the words by their key bits alone is
// stable, and moves 8 bytes per item.
constexpr int kBitsPerAxis = 10;
constexpr int kIndexBits = 32;
static_assert(3 * kBitsPerAxis + kIndexBits <= 64, "a key and an index share one 64-bit word");

/// Stable LSD radix sort of the words by their key bits: three 10-bit digits, the histograms
/// of all three taken in one pass, a pass skipped where every word has the same digit.
void radix_sort(std::vector<std::uint64_t>& items) {
  constexpr int kBits = kBitsPerAxis, kDigits = 3;
  constexpr std::size_t kBuckets = std::size_t(1) << kBits;
  std::vector<std::size_t> count(kDigits * kBuckets, 0);
  const auto digit = [](std::uint64_t it, int d) {
    return std::size_t(it >> (kIndexBits + kBits * d)) & (kBuckets - 1);
  };
  for (const std::uint64_t it : items)
    for (int d = 0; d < kDigits; ++d) ++count[d * kBuckets + digit(it, d)];
  std::vector<std::uint64_t> buffer(items.size());
  for (int d = 0; d < kDigits; ++d) {
    std::size_t* c = &count[d * kBuckets];
    if (*std::max_element(c, c + kBuckets) == items.size()) continue;  // one digit value for all
    std::size_t sum = 0;
    for (std::size_t b = 0; b < kBuckets; ++b) sum += std::exchange(c[b], sum);  // bucket starts
    for (const std::uint64_t it : items) buffer[c[digit(it, d)]++] = it;
    items.swap(buffer);
  }
}

}  // namespace

std::vector<std::uint32_t> morton_order(PointsView points) {
  const std::size_t n = points.size();
  // The index takes the word's low kIndexBits and the order is returned as uint32: checked
  // before either would wrap.
  if (n > std::size_t(std::numeric_limits<std::uint32_t>::max()))
    throw InvalidArgument("there are " + std::to_string(n) +
                          " core points; one run takes at most 4294967295: "
                          "process them in tiles (parameter tile_size)");
  std::vector<std::uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  if (n < 2) return order;
  Vec3 lo = points[0], hi = points[0];
  for (std::size_t i = 1; i < n; ++i) lo = lo.cwiseMin(points[i]), hi = hi.cwiseMax(points[i]);
  const double extent = (hi - lo).maxCoeff();
  const double cells = double((1u << kBitsPerAxis) - 1);
  const double per_extent = extent > 0.0 && std::isfinite(extent) ? cells / extent : 0.0;
  std::vector<std::uint64_t> items(n);
  for (std::size_t i = 0; i < n; ++i) {
    std::uint64_t k = 0;
    for (int a = 0; a < 3; ++a) {
      const double cell = (points.coord(i, a) - lo(a)) * per_extent;  // >= 0: truncation is floor
      k |= spread_bits(cell <= cells ? std::uint64_t(cell) : std::uint64_t(cells)) << a;
    }
    items[i] = k << kIndexBits | i;
  }
  radix_sort(items);  // stable: ties keep input order
  for (std::size_t i = 0; i < n; ++i) order[i] = std::uint32_t(items[i]);
  return order;
}

}  // namespace m3c2::detail
