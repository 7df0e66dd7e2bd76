#pragma once
// M3C2_ASSERT(condition, why): an internal invariant of the engine, whose failure is a bug in it
// (never the caller's input: that gets InvalidArgument). Checked in builds without NDEBUG (Debug)
// and in those that define M3C2_ENABLE_ASSERTS (CMake option M3C2_ASSERTS, on in CI's sanitizer
// build); compiled out of Release builds, where it costs nothing. A failure names the condition
// and its place on stderr and aborts: going on would give wrong numbers or corrupt memory.

#include <cstdio>
#include <cstdlib>

namespace m3c2::detail {

[[noreturn]] inline void assertion_failed(const char* condition, const char* why, const char* file, int line) {
  std::fprintf(stderr, "m3c2: internal invariant violated at %s:%d: %s (%s)\n", file, line, condition, why);
  std::abort();
}

}  // namespace m3c2::detail

#if !defined(NDEBUG) || defined(M3C2_ENABLE_ASSERTS)
#define M3C2_ASSERTS_ACTIVE 1
#define M3C2_ASSERT(condition, why) \
  ((condition) ? void(0) : ::m3c2::detail::assertion_failed(#condition, why, __FILE__, __LINE__))
#else
#define M3C2_ASSERT(condition, why) ((void)0)
#endif
