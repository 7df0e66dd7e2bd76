#pragma once
// Bit interleaving for Morton (Z-order) keys: the octree's cell keys and the core points' order.

#include <cstdint>

namespace m3c2::detail {

/// Spreads the low 21 bits of v so that bit k lands on bit 3k.
inline std::uint64_t spread_bits(std::uint64_t v) {
  v &= 0x1fffffULL;
  v = (v | v << 32) & 0x1f00000000ffffULL;
  v = (v | v << 16) & 0x1f0000ff0000ffULL;
  v = (v | v << 8) & 0x100f00f00f00f00fULL;
  v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
  v = (v | v << 2) & 0x1249249249249249ULL;
  return v;
}

}  // namespace m3c2::detail
