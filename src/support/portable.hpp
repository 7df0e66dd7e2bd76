#pragma once
// Portable stand-ins for compiler extensions the engine uses for speed: a 128-bit unsigned
// integer (the octree's 3 x 42-bit Morton keys), the high half of a 64 x 64-bit product (the
// bootstrap's multiply-shift) and a prefetch hint. GCC and Clang get their builtins; any other
// compiler (or a build with M3C2_PORTABLE_FALLBACKS defined, which CI runs to check that both
// give the same bits) gets standard C++20. The portable types are always defined, so that
// tests/cpp/test_portable.cpp can check them against the builtins.

#include <bit>
#include <cstdint>
#include <type_traits>

#if defined(_MSC_VER) && !defined(__clang__)
#include <intrin.h>
#endif

namespace m3c2::detail {

namespace portable {

/// Unsigned 128-bit integer: the operations the octree's keys need, with unsigned __int128's
/// semantics (shifts by 0..127, conversions keep the low bits).
struct Uint128 {
  std::uint64_t lo = 0, hi = 0;

  constexpr Uint128() = default;
  constexpr Uint128(std::uint64_t low) : lo(low) {}  // NOLINT: implicit, as for the builtin
  constexpr Uint128(std::uint64_t high, std::uint64_t low) : lo(low), hi(high) {}
  template <class T, std::enable_if_t<std::is_integral_v<T>, int> = 0>
  constexpr explicit operator T() const {
    return static_cast<T>(lo);
  }

  friend constexpr bool operator==(Uint128 a, Uint128 b) { return a.lo == b.lo && a.hi == b.hi; }
  friend constexpr Uint128 operator|(Uint128 a, Uint128 b) { return {a.hi | b.hi, a.lo | b.lo}; }
  friend constexpr Uint128 operator&(Uint128 a, Uint128 b) { return {a.hi & b.hi, a.lo & b.lo}; }
  friend constexpr Uint128 operator^(Uint128 a, Uint128 b) { return {a.hi ^ b.hi, a.lo ^ b.lo}; }
  friend constexpr Uint128 operator~(Uint128 a) { return {~a.hi, ~a.lo}; }
  friend constexpr Uint128 operator<<(Uint128 a, int s) {
    if (s == 0) return a;
    if (s >= 64) return {a.lo << (s - 64), 0};
    return {(a.hi << s) | (a.lo >> (64 - s)), a.lo << s};
  }
  friend constexpr Uint128 operator>>(Uint128 a, int s) {
    if (s == 0) return a;
    if (s >= 64) return {0, a.hi >> (s - 64)};
    return {a.hi >> s, (a.lo >> s) | (a.hi << (64 - s))};
  }
  constexpr Uint128& operator|=(Uint128 b) { return *this = *this | b; }
};

constexpr std::uint64_t high64(Uint128 x) { return x.hi; }

/// The high 64 bits of a * b, from four 32 x 32-bit products.
constexpr std::uint64_t mul_high(std::uint64_t a, std::uint64_t b) {
  const std::uint64_t a0 = a & 0xFFFFFFFFu, a1 = a >> 32, b0 = b & 0xFFFFFFFFu, b1 = b >> 32;
  const std::uint64_t p00 = a0 * b0, p01 = a0 * b1, p10 = a1 * b0, p11 = a1 * b1;
  const std::uint64_t middle = (p00 >> 32) + (p01 & 0xFFFFFFFFu) + (p10 & 0xFFFFFFFFu);
  return p11 + (p01 >> 32) + (p10 >> 32) + (middle >> 32);
}

}  // namespace portable

#if defined(__SIZEOF_INT128__) && !defined(M3C2_PORTABLE_FALLBACKS)
#define M3C2_HAS_BUILTIN_INT128 1
__extension__ typedef unsigned __int128 Uint128;  // GCC and Clang
constexpr std::uint64_t high64(Uint128 x) { return std::uint64_t(x >> 64); }
constexpr std::uint64_t mul_high(std::uint64_t a, std::uint64_t b) { return std::uint64_t((Uint128(a) * b) >> 64); }
#else
using portable::high64;
using portable::Uint128;
inline std::uint64_t mul_high(std::uint64_t a, std::uint64_t b) {
#if defined(_MSC_VER) && !defined(__clang__) && defined(_M_X64) && !defined(M3C2_PORTABLE_FALLBACKS)
  return __umulh(a, b);
#else
  return portable::mul_high(a, b);
#endif
}
#endif

/// Asks for the cache line at `p` ahead of its use; a hint only (no effect on results).
inline void prefetch(const void* p) {
#if (defined(__GNUC__) || defined(__clang__)) && !defined(M3C2_PORTABLE_FALLBACKS)
  __builtin_prefetch(p);
#else
  (void)p;
#endif
}

}  // namespace m3c2::detail
