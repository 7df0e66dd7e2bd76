// m3c2::match_rows against a brute-force oracle: the first identical row in input order, nullopt
// when a query is no row; -0.0 equals 0.0, NaN equals nothing, rows one ulp apart differ.

#include "test_support.hpp"

#include <optional>

namespace m3c2::test {
namespace {

std::optional<std::vector<std::uint64_t>> oracle(const Cloud& points, const Cloud& queries) {
  std::vector<std::uint64_t> out;
  for (std::size_t k = 0; k < queries.size(); ++k) {
    std::size_t i = 0;
    while (i < points.size() && !(points[i] == queries[k])) ++i;  // Eigen's ==: exact, as numbers
    if (i == points.size()) return std::nullopt;
    out.push_back(i);
  }
  return out;
}

/// Coarse random rows (many duplicates), each preceded by its neighbours one ulp off on an axis.
Cloud rows_with_near_twins(std::uint32_t seed, std::size_t n) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> tenth(0, 30);
  Cloud c;
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 p(tenth(rng) / 10.0, tenth(rng) / 10.0, tenth(rng) / 10.0);
    for (int a = 0; a < 3; ++a) {
      Vec3 near = p;
      near[a] = std::nextafter(p[a], 10.0);
      c.add(near);
    }
    c.add(p);
  }
  return c;
}

TEST(MatchRows, FirstIdenticalRowInInputOrder) {
  const Cloud points = rows_with_near_twins(1, 500);
  Cloud queries;
  for (std::size_t i = 3; i < points.size(); i += 28) queries.add(points[i]);
  queries.add(points[7]);  // a row that is also a later row: the first is taken
  const auto found = match_rows(points.view(), queries.view());
  ASSERT_TRUE(found.has_value());
  EXPECT_EQ(*found, *oracle(points, queries));
}

TEST(MatchRows, NulloptWhenAQueryIsNoRow) {
  const Cloud points = rows_with_near_twins(2, 100);
  Cloud queries;
  queries.add(points[3]);
  queries.add(points[3].x(), points[3].y(), std::nextafter(points[3].z(), -10.0));  // one ulp below: no row
  EXPECT_FALSE(match_rows(points.view(), queries.view()).has_value());
  Cloud empty;
  EXPECT_FALSE(match_rows(empty.view(), queries.view()).has_value());
  EXPECT_TRUE(match_rows(points.view(), empty.view())->empty());
}

TEST(MatchRows, NegativeZeroEqualsZeroAndNanEqualsNothing) {
  Cloud points;
  points.add(kNaN, 0.0, 0.0);
  points.add(1.0, 0.0, 2.0);
  points.add(0.0, 0.0, 0.0);
  Cloud queries;
  queries.add(-0.0, 0.0, -0.0);
  queries.add(1.0, -0.0, 2.0);
  EXPECT_EQ(*match_rows(points.view(), queries.view()), (std::vector<std::uint64_t>{2, 1}));
  queries.add(kNaN, 0.0, 0.0);
  EXPECT_FALSE(match_rows(points.view(), queries.view()).has_value());
}

TEST(MatchRows, TheSameArrayIsTheIdentity) {
  const Cloud points = rows_with_near_twins(3, 50);
  std::vector<std::uint64_t> identity(points.size());
  for (std::size_t i = 0; i < identity.size(); ++i) identity[i] = i;
  EXPECT_EQ(*match_rows(points.view(), points.view()), identity);
}

}  // namespace
}  // namespace m3c2::test
