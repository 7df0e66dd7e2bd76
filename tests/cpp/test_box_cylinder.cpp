// The box-against-cylinder bound (src/index/cylinder.hpp, box_may_meet) and the k-d tree's
// pruned selection (src/index/kdtree.hpp, select): the bound never rejects a box holding a point
// of the cylinder, even at georeferenced coordinates, it does reject boxes clear of it, and a
// selection pruned by it keeps exactly the points a scan of every point keeps.

#include "index/cylinder.hpp"
#include "index/cylinder_leaf.hpp"
#include "index/kdtree.hpp"

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace m3c2::detail {
namespace {

Vec3 random_unit(std::mt19937_64& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  const Vec3 v(g(rng), g(rng), g(rng));
  return v / v.norm();
}

Cylinder random_cylinder(std::mt19937_64& rng, const Vec3& origin) {
  std::uniform_real_distribution<double> u(0.05, 2.0);
  return Cylinder{origin, random_unit(rng), u(rng), -u(rng), u(rng)};
}

bool holds(const Vec3& p, const Cylinder& cyl) {
  double t = 0.0;
  return cylinder_holds(p.data(), cyl, cyl.radius * cyl.radius, &t);
}

TEST(BoxCylinder, NeverRejectsABoxHoldingAPointOfTheCylinder) {
  std::mt19937_64 rng(20261204);
  std::uniform_real_distribution<double> u(-1.0, 1.0), extent(0.0, 1.5);
  for (const Vec3& origin : {Vec3(0.0, 0.0, 0.0), Vec3(512345.678, 5412345.321, 312.5)}) {
    int boxes_tested = 0;
    for (int trial = 0; trial < 20000; ++trial) {
      const Cylinder cyl = random_cylinder(rng, origin);
      // A point of the cylinder, often on its boundary (radius or an end), inside a random box.
      const Vec3 n = cyl.normal;
      Vec3 side = n.cross(random_unit(rng));
      side /= side.norm();
      const double t = trial % 3 == 0 ? cyl.t_max : cyl.t_min + (cyl.t_max - cyl.t_min) * (0.5 + 0.5 * u(rng));
      const double r = trial % 2 == 0 ? cyl.radius : cyl.radius * (0.5 + 0.5 * u(rng));
      const Vec3 p = origin + t * n + r * side;
      if (!holds(p, cyl)) continue;  // rounding put a boundary point just outside: not a case
      std::array<double, 3> lo{}, hi{};
      for (int a = 0; a < 3; ++a) {
        lo[a] = p(a) - (trial % 5 == 0 ? 0.0 : extent(rng));
        hi[a] = p(a) + (trial % 7 == 0 ? 0.0 : extent(rng));
      }
      ASSERT_TRUE(box_may_meet(lo, hi, cyl)) << "trial " << trial;
      ++boxes_tested;
    }
    EXPECT_GT(boxes_tested, 10000);
  }
}

TEST(BoxCylinder, RejectsBoxesClearOfTheCylinder) {
  const Cylinder up{Vec3(10.0, 20.0, 30.0), Vec3(0.0, 0.0, 1.0), 0.5, -2.0, 2.0};
  // beside the axis, beyond the radius (the box's nearest corner at 0.5 + 0.1 in x)
  EXPECT_FALSE(box_may_meet({10.6, 19.9, 29.0}, {11.0, 20.1, 31.0}, up));
  // within the radius, beyond the far end
  EXPECT_FALSE(box_may_meet({9.9, 19.9, 32.1}, {10.1, 20.1, 33.0}, up));
  // a corner box whose nearest corner is 0.6 from the axis diagonally (its faces reach within 0.5)
  EXPECT_FALSE(box_may_meet({10.0 + 0.6 / std::sqrt(2.0), 20.0 + 0.6 / std::sqrt(2.0), 29.0}, {11.0, 21.0, 31.0}, up));
  // the same boxes touching the cylinder
  EXPECT_TRUE(box_may_meet({10.5, 19.9, 29.0}, {11.0, 20.1, 31.0}, up));
  EXPECT_TRUE(box_may_meet({9.9, 19.9, 32.0}, {10.1, 20.1, 33.0}, up));
  EXPECT_TRUE(box_may_meet({10.3, 20.3, 29.0}, {11.0, 21.0, 31.0}, up));
}

TEST(BoxCylinder, PrunedSelectionKeepsWhatAScanKeeps) {
  std::mt19937_64 rng(7);
  const Vec3 origin(512345.678, 5412345.321, 312.5);
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  std::vector<double> xyz;
  for (int i = 0; i < 20000; ++i)
    for (int a = 0; a < 3; ++a) xyz.push_back(origin(a) + (a == 2 ? 0.2 : 1.0) * u(rng));
  const PointsView cloud(xyz.data(), xyz.size() / 3);
  const KdTree tree(cloud);
  std::size_t kept_total = 0;
  for (int q = 0; q < 300; ++q) {
    Cylinder cyl = random_cylinder(rng, origin + Vec3(u(rng), u(rng), 0.2 * u(rng)));
    const auto keep = [&](const double* p) { return holds(Vec3(p[0], p[1], p[2]), cyl); };
    std::vector<std::uint32_t> pruned, scanned;
    tree.select([&](const auto& lo, const auto& hi) { return !box_may_meet(lo, hi, cyl); }, keep, pruned);
    for (std::uint32_t i = 0; i < cloud.size(); ++i)
      if (keep(xyz.data() + 3 * std::size_t(i))) scanned.push_back(i);
    std::sort(pruned.begin(), pruned.end());
    ASSERT_EQ(pruned, scanned) << "query " << q;
    kept_total += pruned.size();
  }
  EXPECT_GT(kept_total, 1000u);  // the cylinders do meet the cloud
}

}  // namespace
}  // namespace m3c2::detail
