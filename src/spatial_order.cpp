#include "spatial_order.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

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

}  // namespace

std::vector<std::uint32_t> morton_order(PointsView points) {
  const std::size_t n = points.size();
  std::vector<std::uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  if (n < 2) return order;
  Vec3 lo = points[0], hi = points[0];
  for (std::size_t i = 1; i < n; ++i) lo = lo.cwiseMin(points[i]), hi = hi.cwiseMax(points[i]);
  const double extent = std::max((hi - lo).maxCoeff(), 1e-300);
  const double cells = double((1u << 21) - 1);
  std::vector<std::uint64_t> key(n);
  for (std::size_t i = 0; i < n; ++i) {
    std::uint64_t k = 0;
    for (int a = 0; a < 3; ++a)
      k |= spread_bits(std::uint64_t(std::floor((points.coord(i, a) - lo(a)) / extent * cells))) << a;
    key[i] = k;
  }
  std::stable_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return key[a] < key[b]; });
  return order;
}

}  // namespace m3c2::detail
