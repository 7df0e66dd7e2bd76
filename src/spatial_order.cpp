#include "spatial_order.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <utility>

namespace m3c2::detail {
namespace {

/// Spreads the low 21 bits of v so that bit k lands on bit 3k.
std::uint64_t spread_bits(std::uint64_t v) {
  v &= 0x1fffffULL;
  v = (v | v << 32) & 0x1f00000000ffffULL;
  v = (v | v << 16) & 0x1f0000ff0000ffULL;
  v = (v | v << 8) & 0x100f00f00f00f00fULL;
  v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
  v = (v | v << 2) & 0x1249249249249249ULL;
  return v;
}

/// Stable LSD radix sort of (key, index) pairs by key: 12-bit digits, the histograms of all
/// three digits taken in one pass, and a pass skipped where every key has the same digit.
struct Keyed {
  std::uint64_t key;
  std::uint32_t index;
};

constexpr int kBitsPerAxis = 12;  // 4096 cells per axis: finer buys no locality, only passes

void radix_sort(std::vector<Keyed>& items) {
  constexpr int kBits = 12, kDigits = 3;  // 36 = 3 x kBitsPerAxis
  constexpr std::size_t kBuckets = std::size_t(1) << kBits;
  std::vector<std::size_t> count(kDigits * kBuckets, 0);
  for (const Keyed& it : items)
    for (int d = 0; d < kDigits; ++d) ++count[d * kBuckets + ((it.key >> (kBits * d)) & (kBuckets - 1))];
  std::vector<Keyed> buffer(items.size());
  for (int d = 0; d < kDigits; ++d) {
    std::size_t* c = &count[d * kBuckets];
    if (*std::max_element(c, c + kBuckets) == items.size()) continue;  // one digit value for all
    std::size_t sum = 0;
    for (std::size_t b = 0; b < kBuckets; ++b) sum += std::exchange(c[b], sum);  // bucket starts
    for (const Keyed& it : items) buffer[c[(it.key >> (kBits * d)) & (kBuckets - 1)]++] = it;
    items.swap(buffer);
  }
}

}  // namespace

std::vector<std::uint32_t> morton_order(PointsView points) {
  const std::size_t n = points.size();
  std::vector<std::uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  if (n < 2) return order;
  Vec3 lo = points[0], hi = points[0];
  for (std::size_t i = 1; i < n; ++i) lo = lo.cwiseMin(points[i]), hi = hi.cwiseMax(points[i]);
  const double extent = (hi - lo).maxCoeff();
  const double cells = double((1u << kBitsPerAxis) - 1);
  const double per_extent = extent > 0.0 && std::isfinite(extent) ? cells / extent : 0.0;
  std::vector<Keyed> items(n);
  for (std::size_t i = 0; i < n; ++i) {
    std::uint64_t k = 0;
    for (int a = 0; a < 3; ++a) {
      const double cell = (points.coord(i, a) - lo(a)) * per_extent;  // >= 0: truncation is floor
      k |= spread_bits(cell <= cells ? std::uint64_t(cell) : std::uint64_t(cells)) << a;
    }
    items[i] = {k, std::uint32_t(i)};
  }
  radix_sort(items);  // stable: ties keep input order
  for (std::size_t i = 0; i < n; ++i) order[i] = items[i].index;
  return order;
}

}  // namespace m3c2::detail
