// The k-d tree's nearest-point query (src/index/kdtree.hpp, KdTree::nearest; PB-M3C2's votes and
// ICP's pairs): against a scan of every point, the point of least squared distance within
// max_distance (inclusive), the first in tree order on a tie, at georeferenced coordinates, with
// duplicated points and on a grid where most queries are equidistant from several points.

#include "index/distance.hpp"
#include "index/kdtree.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

namespace m3c2::detail {
namespace {

/// The points' original indices in tree order (select() visits the leaves in slot order).
std::vector<std::uint32_t> tree_order(const KdTree& tree) {
  std::vector<std::uint32_t> order;
  tree.select([](const auto&, const auto&) { return false; }, [](const double*) { return true; }, order);
  return order;
}

/// The scan: least squared distance <= max_distance^2, the first in tree order on a tie.
std::uint32_t scanned_nearest(const std::vector<double>& xyz, const std::vector<std::uint32_t>& order, const Vec3& q,
                              double max_distance) {
  double best2 = max_distance * max_distance;
  std::uint32_t best = KdTree::kNone;
  for (const std::uint32_t i : order) {
    const double d2 = squared_distance(xyz.data() + 3 * std::size_t(i), q);
    if (d2 < best2 || (d2 == best2 && best == KdTree::kNone)) best2 = d2, best = i;
  }
  return best;
}

void expect_as_scanned(const std::vector<double>& xyz, const std::vector<Vec3>& queries, double max_distance) {
  const KdTree tree(PointsView(xyz.data(), xyz.size() / 3));
  const std::vector<std::uint32_t> order = tree_order(tree);
  ASSERT_EQ(order.size(), xyz.size() / 3);
  std::size_t found = 0;
  for (std::size_t k = 0; k < queries.size(); ++k) {
    const std::uint32_t expected = scanned_nearest(xyz, order, queries[k], max_distance);
    ASSERT_EQ(tree.nearest(queries[k], max_distance), expected) << "query " << k;
    found += expected != KdTree::kNone;
  }
  EXPECT_GT(found, 0u);              // the radius keeps some
  EXPECT_LT(found, queries.size());  // and refuses some: both branches are tested
}

TEST(KdTreeNearest, IsTheScansPointAtGeoreferencedCoordinatesWithDuplicates) {
  std::mt19937_64 rng(11);
  const Vec3 origin(512345.678, 5412345.321, 312.5);
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  std::vector<double> xyz;
  for (int i = 0; i < 6000; ++i)
    for (int a = 0; a < 3; ++a) xyz.push_back(origin(a) + (a == 2 ? 0.3 : 1.0) * u(rng));
  for (int i = 0; i < 3000; i += 3)  // every third point twice: exact ties
    for (int a = 0; a < 3; ++a) xyz.push_back(xyz[3 * std::size_t(i) + std::size_t(a)]);
  std::vector<Vec3> queries;
  for (int k = 0; k < 2000; ++k) {
    if (k % 4 == 0) {  // at a duplicated point: distance 0 to two slots
      const std::size_t i = 3 * std::size_t(k % 1000);
      queries.emplace_back(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
    } else {
      queries.push_back(origin + Vec3(1.6 * u(rng), 1.6 * u(rng), 0.5 * u(rng)));
    }
  }
  expect_as_scanned(xyz, queries, 0.12);
}

TEST(KdTreeNearest, BreaksEquidistantTiesByTreeOrderOnAGrid) {
  std::vector<double> xyz;
  for (int i = 0; i < 40; ++i)
    for (int j = 0; j < 40; ++j)
      for (double v : {0.25 * i, 0.25 * j, 0.0}) xyz.push_back(v);
  std::vector<Vec3> queries;
  for (int i = -2; i < 82; ++i)  // cell centres and edge midpoints: 2 or 4 points at the least distance
    for (int j = -2; j < 82; ++j) queries.emplace_back(0.125 * i, 0.125 * j, 0.0);
  expect_as_scanned(xyz, queries, 0.125 * std::sqrt(2.0));
}

TEST(KdTreeNearest, TheRadiusIsInclusiveAndAnEmptyTreeHasNone) {
  const std::vector<double> xyz{0.0, 0.0, 0.0, 3.0, 0.0, 0.0};
  const KdTree tree(PointsView(xyz.data(), 2));
  EXPECT_EQ(tree.nearest(Vec3(1.0, 0.0, 0.0), 1.0), 0u);  // exactly at max_distance
  EXPECT_EQ(tree.nearest(Vec3(1.0, 0.0, 0.0), std::nextafter(1.0, 0.0)), KdTree::kNone);
  EXPECT_EQ(tree.nearest(Vec3(2.0, 0.0, 0.0), 5.0), 1u);
  EXPECT_EQ(tree.nearest(Vec3(1.5, 0.0, 0.0), 5.0), 0u);  // equidistant: the first in tree order
  const std::vector<double> none;
  EXPECT_EQ(KdTree(PointsView(none.data(), 0)).nearest(Vec3(0.0, 0.0, 0.0), 1.0), KdTree::kNone);
}

}  // namespace
}  // namespace m3c2::detail
