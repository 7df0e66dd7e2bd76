// The standard C++ stand-ins of src/support/portable.hpp against the compiler's builtins, on the
// operations the engine uses, for fixed-seed random operands and the edge cases (shifts by 0,
// 63, 64, 127; all-ones words). Where the compiler has no unsigned __int128 the reference is
// the 128-bit arithmetic written out here (mul_high checked by its defining identity).

#include "support/portable.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <cstdint>
#include <random>

namespace m3c2::test {
namespace {

using detail::portable::Uint128;

#if defined(__SIZEOF_INT128__)
__extension__ typedef unsigned __int128 Native;

Native native(Uint128 x) { return Native(x.hi) << 64 | x.lo; }

::testing::AssertionResult Same(Uint128 p, Native n) {
  if (p.lo == std::uint64_t(n) && p.hi == std::uint64_t(n >> 64)) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << std::hex << "portable " << p.hi << ":" << p.lo << " builtin "
                                       << std::uint64_t(n >> 64) << ":" << std::uint64_t(n);
}

TEST(Portable, Uint128OperationsMatchTheBuiltin) {
  std::mt19937_64 rng(20240611);
  const std::uint64_t edges[] = {0, 1, ~0ULL, 1ULL << 63, 0x9E3779B97F4A7C15ULL};
  for (int trial = 0; trial < 2000; ++trial) {
    const Uint128 a = trial < 25 ? Uint128(edges[trial / 5], edges[trial % 5]) : Uint128(rng(), rng());
    const Uint128 b(rng(), rng());
    const Native na = native(a), nb = native(b);
    EXPECT_TRUE(Same(a | b, na | nb));
    EXPECT_TRUE(Same(a & b, na & nb));
    EXPECT_TRUE(Same(a ^ b, na ^ nb));
    EXPECT_TRUE(Same(~a, ~na));
    for (const int s : {0, 1, 3, 21, 42, 63, 64, 65, 100, 126, 127, int(rng() % 128)}) {
      EXPECT_TRUE(Same(a << s, na << s)) << "shift " << s;
      EXPECT_TRUE(Same(a >> s, na >> s)) << "shift " << s;
    }
    Uint128 c = a;
    c |= b;
    EXPECT_TRUE(Same(c, na | nb));
    EXPECT_EQ(a == b, na == nb);
    EXPECT_TRUE(a == a);
    EXPECT_EQ(std::uint32_t(a), std::uint32_t(na));
    EXPECT_EQ(std::uint64_t(a), std::uint64_t(na));
    EXPECT_EQ(detail::portable::high64(a), std::uint64_t(na >> 64));
    const std::uint64_t x = rng(), y = trial < 25 ? edges[trial % 5] : rng();
    EXPECT_EQ(detail::portable::mul_high(x, y), std::uint64_t((Native(x) * y) >> 64)) << x << " * " << y;
    EXPECT_EQ(detail::mul_high(x, y), detail::portable::mul_high(x, y));
  }
}
#endif

TEST(Portable, MulHighSatisfiesItsDefinition) {
  // a * b = high 2^64 + low, with low the wrapped product: checked through 32-bit halves.
  std::mt19937_64 rng(7);
  for (int trial = 0; trial < 2000; ++trial) {
    const std::uint64_t a = rng(), b = trial % 7 == 0 ? ~0ULL : rng();
    const std::uint64_t hi = detail::portable::mul_high(a, b), lo = a * b;
    // (h, l) = sum over the set bits of b of a << bit, added with carries (shift-and-add).
    std::uint64_t h = 0, l = 0;
    for (int bit = 0; bit < 64; ++bit)
      if (b >> bit & 1) {
        const Uint128 term = Uint128(a) << bit;
        const std::uint64_t before = l;
        l += term.lo;
        h += term.hi + (l < before);
      }
    EXPECT_EQ(l, lo);
    EXPECT_EQ(h, hi) << a << " * " << b;
  }
  EXPECT_EQ(detail::portable::mul_high(~0ULL, ~0ULL), ~0ULL - 1);
  EXPECT_EQ(detail::portable::mul_high(1ULL << 32, 1ULL << 32), 1u);
}

}  // namespace
}  // namespace m3c2::test
