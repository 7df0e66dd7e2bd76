// Counts that would overflow the engine's 32-bit indexes are refused before anything is read or
// allocated, with a message naming the parameter that avoids them (tile_size), not a
// command-line flag a C++ caller does not have. The views are never dereferenced: each check
// comes first, so a dummy pointer with a huge count tests it without 100 GB of points.

#include "index/kdtree.hpp"
#include "index/octree.hpp"
#include "index/spatial_order.hpp"
#include "test_support.hpp"

#include <string>

namespace m3c2::test {
namespace {

const double kDummy[3] = {0.0, 0.0, 0.0};
constexpr std::size_t k2To32 = std::size_t(1) << 32;

template <class F>
std::string message_of(F&& f) {
  try {
    f();
  } catch (const InvalidArgument& e) {
    return e.what();
  }
  return "";
}

TEST(OverflowGuards, CorePointsBeyond32BitIndexesAreRefused) {
  const std::string m = message_of([] { detail::morton_order(PointsView(kDummy, k2To32)); });
  EXPECT_NE(m.find("4294967296 core points"), std::string::npos) << m;
  EXPECT_NE(m.find("tile_size"), std::string::npos) << m;
  EXPECT_EQ(m.find("--"), std::string::npos) << m;
}

TEST(OverflowGuards, AnOctreeOfMoreThan2To32Minus2PointsIsRefused) {
  const detail::OctreeGrid grid = detail::octree_grid(1.0, 1.0);
  const std::string m =
      message_of([&] { detail::Octree(PointsView(kDummy, k2To32 - 1), grid, {.cloud_name = "cloud"}); });
  EXPECT_NE(m.find("4294967295 points"), std::string::npos) << m;
  EXPECT_NE(m.find("tile_size"), std::string::npos) << m;
  EXPECT_EQ(m.find("--"), std::string::npos) << m;
}

TEST(OverflowGuards, AKdTreeOfMoreThan2To32Minus2PointsIsRefused) {
  const std::string m = message_of([] { detail::KdTree(PointsView(kDummy, k2To32 - 1)); });
  EXPECT_NE(m.find("4294967295 points"), std::string::npos) << m;
  EXPECT_NE(m.find("tile_size"), std::string::npos) << m;
}

TEST(OverflowGuards, TheLargestAcceptedCountsStillPass) {
  // Non-vacuity: the bounds are where stated, not lower (small real inputs pass the same checks).
  const Cloud c = plane_grid(Vec3::Zero(), Vec3::UnitZ(), 2, 0.1);
  EXPECT_EQ(detail::morton_order(c.view()).size(), c.size());
}

}  // namespace
}  // namespace m3c2::test
