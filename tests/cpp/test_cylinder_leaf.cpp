// The cylinder test over a leaf (src/index/cylinder_leaf.hpp): two points at a time in SSE2 lanes,
// against the one-point test, bit for bit, on random points, on points exactly on the
// boundaries and at every leaf length (the odd point left to the scalar loop).

#include "index/cylinder_leaf.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace m3c2::detail {
namespace {

struct Kept {
  std::vector<double> t;
  std::vector<std::uint32_t> index;
};

Kept one_at_a_time(const std::vector<double>& xyz, const Cylinder& cyl, const std::vector<std::uint32_t>& original) {
  Kept k;
  for (std::size_t j = 0; j < original.size(); ++j) {
    double t = 0.0;
    if (cylinder_holds(xyz.data() + 3 * j, cyl, cyl.radius * cyl.radius, &t)) {
      k.t.push_back(t);
      k.index.push_back(original[j]);
    }
  }
  return k;
}

Kept leaf(const std::vector<double>& xyz, const Cylinder& cyl, const std::vector<std::uint32_t>& original,
          bool with_index) {
  const auto n = static_cast<std::uint32_t>(original.size());
  Kept k;
  k.t.assign(n, -1.0);
  k.index.assign(n, 0);
  const std::uint32_t kept = cylinder_leaf(xyz.data(), n, cyl, cyl.radius * cyl.radius, k.t.data(),
                                           with_index ? k.index.data() : nullptr, original.data());
  k.t.resize(kept);
  k.index.resize(with_index ? kept : 0);
  return k;
}

void expect_same_bits(const Kept& a, const Kept& b, bool with_index) {
  ASSERT_EQ(a.t.size(), b.t.size());
  for (std::size_t i = 0; i < a.t.size(); ++i) {
    EXPECT_EQ(std::bit_cast<std::uint64_t>(a.t[i]), std::bit_cast<std::uint64_t>(b.t[i])) << i;
    if (with_index) {
      EXPECT_EQ(a.index[i], b.index[i]) << i;
    }
  }
}

TEST(CylinderLeaf, RandomPointsGiveTheOnePointTestsBitsAtEveryLength) {
  std::mt19937_64 rng(31);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::size_t inside = 0, outside = 0;
  for (std::uint32_t n = 0; n <= 41; ++n)
    for (int trial = 0; trial < 20; ++trial) {
      Cylinder cyl;
      cyl.core = Vec3(5e5 + u(rng), 4e6 + u(rng), 100.0 + u(rng));
      cyl.normal = Vec3(u(rng), u(rng), u(rng)).normalized();
      cyl.radius = 0.3 + 0.3 * std::abs(u(rng));
      cyl.t_min = -0.5 * std::abs(u(rng)), cyl.t_max = 0.5 * std::abs(u(rng));
      std::vector<double> xyz;
      std::vector<std::uint32_t> original;
      for (std::uint32_t j = 0; j < n; ++j) {
        const Vec3 p = cyl.core + Vec3(u(rng), u(rng), u(rng));
        xyz.insert(xyz.end(), {p.x(), p.y(), p.z()});
        original.push_back(1000 + 7 * j);
      }
      const Kept expected = one_at_a_time(xyz, cyl, original);
      inside += expected.t.size(), outside += n - expected.t.size();
      for (const bool with_index : {false, true})
        expect_same_bits(leaf(xyz, cyl, original, with_index), expected, with_index);
    }
  EXPECT_GT(inside, 500u);  // the fixture exercises both outcomes
  EXPECT_GT(outside, 1000u);
}

TEST(CylinderLeaf, PointsExactlyOnEachBoundaryAreInsideAndJustBeyondAreNot) {
  // Axis z through the origin, radius 0.5, t in [-0.25, 0.75]: every quantity exact in binary.
  Cylinder cyl;
  cyl.core = Vec3::Zero();
  cyl.normal = Vec3::UnitZ();
  cyl.radius = 0.5;
  cyl.t_min = -0.25, cyl.t_max = 0.75;
  const double above = std::nextafter(0.75, 1.0), below = std::nextafter(-0.25, -1.0), wide = std::nextafter(0.5, 1.0);
  const std::vector<Vec3> points = {{0.5, 0.0, 0.0},   {0.0, -0.5, 0.75}, {-0.5, 0.0, -0.25}, {0.0, 0.0, above},
                                    {0.0, 0.0, below}, {wide, 0.0, 0.0},  {0.0, 0.0, 0.0}};
  const std::vector<bool> expected_inside = {true, true, true, false, false, false, true};
  std::vector<double> xyz;
  std::vector<std::uint32_t> original;
  for (std::size_t j = 0; j < points.size(); ++j) {
    xyz.insert(xyz.end(), {points[j].x(), points[j].y(), points[j].z()});
    original.push_back(static_cast<std::uint32_t>(j));
  }
  const Kept k = leaf(xyz, cyl, original, true);
  std::vector<std::uint32_t> want;
  for (std::uint32_t j = 0; j < expected_inside.size(); ++j)
    if (expected_inside[j]) want.push_back(j);
  EXPECT_EQ(k.index, want);
  expect_same_bits(k, one_at_a_time(xyz, cyl, original), true);
}

}  // namespace
}  // namespace m3c2::detail
