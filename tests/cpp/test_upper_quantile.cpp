// detail::UpperQuantile (src/series/upper_quantile.hpp) against what 4D-OBC's region growing computed
// before it: a descending ordered set of the distinct values, walked to floor(0.05 n), after every
// value, on seeded random values with many repeats and both signed zeros.

#include "series/upper_quantile.hpp"

#include <gtest/gtest.h>

#include <cstddef>
#include <functional>
#include <iterator>
#include <random>
#include <set>

namespace m3c2::test {

TEST(UpperQuantile, IsTheOrderedSetWalkedToItsRank) {
  std::mt19937_64 rng(19);
  for (int trial = 0; trial < 20; ++trial) {
    std::uniform_int_distribution<int> level(0, trial < 10 ? 50 : 5000);  // few distinct values, then many
    detail::UpperQuantile quantile(0.0);
    std::set<double, std::greater<double>> used{0.0};
    for (int i = 0; i < 3000; ++i) {
      const int k = level(rng);
      const double v = k == 0 ? (i % 2 ? -0.0 : 0.0) : k / 7.0;
      quantile.insert(v);
      used.insert(v);
      auto it = used.begin();
      std::advance(it, static_cast<std::ptrdiff_t>(0.05 * double(used.size())));
      ASSERT_EQ(quantile.value(), *it) << "trial " << trial << ", value " << i;
    }
  }
}

}  // namespace m3c2::test
