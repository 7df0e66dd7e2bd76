// M3C2_ASSERT (src/support/assert.hpp): active in this build when NDEBUG is not defined or
// M3C2_ENABLE_ASSERTS is (CI's sanitizer build), and then a violated invariant aborts with its
// condition named; compiled out otherwise (the condition is not even evaluated).

#include "support/assert.hpp"

#include <gtest/gtest.h>

namespace m3c2::test {
namespace {

#if defined(M3C2_ASSERTS_ACTIVE)
TEST(AssertDeathTest, AViolatedInvariantAbortsNamingIt) {
  const int depth = 50;
  EXPECT_DEATH(M3C2_ASSERT(depth < 44, "the depth bound"), "internal invariant violated.*depth < 44.*the depth bound");
}
TEST(Assert, AHeldInvariantPasses) {
  int evaluated = 0;
  M3C2_ASSERT(++evaluated == 1, "evaluated once");
  EXPECT_EQ(evaluated, 1);
}
#else
TEST(Assert, CompiledOutOfReleaseBuilds) {
  int evaluated = 0;
  M3C2_ASSERT(++evaluated == 1, "not evaluated");
  EXPECT_EQ(evaluated, 0);
}
#endif

}  // namespace
}  // namespace m3c2::test
