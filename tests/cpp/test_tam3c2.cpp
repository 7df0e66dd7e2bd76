// Time-adaptive M3C2 (include/m3c2/tam3c2.hpp) on scenes whose answer is known by hand: a flat
// plane shifted by a known offset per epoch; the nearest-in-time rule and the window's cap; the
// same bits for any thread count. The numbers against an independent implementation are
// tests/python/series/test_tam3c2.py's (a brute-force numpy TAM3C2).
#include <m3c2/errors.hpp>
#include <m3c2/tam3c2.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

namespace {

/// A square grid of side `n` points, spacing 0.1, at height z.
std::vector<double> plane(int n, double z) {
  std::vector<double> xyz;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) xyz.insert(xyz.end(), {0.1 * i - 0.1 * (n / 2), 0.1 * j - 0.1 * (n / 2), z});
  return xyz;
}

m3c2::Tam3c2Params params() {
  m3c2::Tam3c2Params p;
  p.normal_radii = {0.5};
  p.window_ratios = {1.0};
  p.cylinder_radius = 0.25;
  p.max_distance = 2.0;
  p.min_points = 5;
  return p;
}

TEST(Tam3c2, FlatPlanesGiveTheirOffsets) {
  // Epoch e at height 0.1 e, times 0..3: each side's cylinder holds >= 5 points of its own epoch.
  std::vector<std::vector<double>> clouds;
  for (int e = 0; e < 4; ++e) clouds.push_back(plane(21, 0.1 * e));
  std::vector<m3c2::PointsView> views;
  for (auto& c : clouds) views.emplace_back(c.data(), c.size() / 3);
  m3c2::Tam3c2Pool pool(views, {0.0, 1.0, 2.0, 3.0});
  const std::vector<double> core{0.0, 0.0, 0.0};
  auto p = params();
  p.registration_error = 0.01;
  const auto r = m3c2::tam3c2(p, pool, 0, {1, 2, 3}, {core.data(), 1});
  EXPECT_NEAR(std::abs(r.normal[2]), 1.0, 1e-12);
  EXPECT_GE(r.normal[2], 0.0);  // towards +z
  for (int j = 0; j < 3; ++j) {
    EXPECT_NEAR(r.distance[j], 0.1 * (j + 1), 1e-12);
    EXPECT_NEAR(r.lod[j], 0.01, 1e-12);  // flat: no spread
    EXPECT_EQ(r.epochs1[j], 1u);
    EXPECT_EQ(r.epochs2[j], 1u);
  }
  p.lod = m3c2::Tam3c2Lod::kT;  // (almost) no spread: the registration error, whatever the quantile
  const auto t = m3c2::tam3c2(p, pool, 0, {1, 2, 3}, {core.data(), 1});
  for (int j = 0; j < 3; ++j) EXPECT_NEAR(t.lod[j], 0.01, 1e-12);
}

TEST(Tam3c2, NormalsPointToEachCorePointsOrientation) {
  // The planes of FlatPlanesGiveTheirOffsets; core points 0 and 1 at the centre, 2 far from every
  // point (no normal: it keeps its orientation, made unit). Orientations: down, not finite (the
  // parameters' +z), and (3, 0, 4).
  std::vector<std::vector<double>> clouds;
  for (int e = 0; e < 4; ++e) clouds.push_back(plane(21, 0.1 * e));
  std::vector<m3c2::PointsView> views;
  for (auto& c : clouds) views.emplace_back(c.data(), c.size() / 3);
  m3c2::Tam3c2Pool pool(views, {0.0, 1.0, 2.0, 3.0});
  const std::vector<double> core{0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 50.0, 50.0, 0.0};
  const std::vector<double> towards{0.0, 0.0, -2.0, NAN, 0.0, 1.0, 3.0, 0.0, 4.0};
  const auto r = m3c2::tam3c2(params(), pool, 0, {1, 2, 3}, {core.data(), 3}, {towards.data(), 3});
  EXPECT_NEAR(r.normal[2], -1.0, 1e-12);
  EXPECT_NEAR(r.normal[5], 1.0, 1e-12);
  EXPECT_EQ(r.scale[2], -1);
  EXPECT_EQ(r.normal[6], 0.6);
  EXPECT_EQ(r.normal[8], 0.8);
  for (int j = 0; j < 3; ++j) {
    EXPECT_NEAR(r.distance[j], -0.1 * (j + 1), 1e-12);  // the same change, seen along -z
    EXPECT_NEAR(r.distance[3 + j], 0.1 * (j + 1), 1e-12);
    EXPECT_TRUE(std::isnan(r.distance[6 + j]));
  }
  EXPECT_THROW(m3c2::tam3c2(params(), pool, 0, {1}, {core.data(), 3}, {towards.data(), 2}), m3c2::InvalidArgument);
}

TEST(Tam3c2, BorrowsNearestEpochsWithinTheCap) {
  // The target epoch (time 10) has 1 point in the cylinder; its neighbours at 9 and 12 have a
  // plane each: nearest first takes 9, then stops (enough points). With the cap at 0.05 of the
  // gap (W = 0.5) nothing is borrowed and the target side has too few points.
  std::vector<std::vector<double>> clouds{plane(21, 0.0), plane(21, 0.2), {0.0, 0.0, 0.5}, plane(21, 0.9)};
  std::vector<m3c2::PointsView> views;
  for (auto& c : clouds) views.emplace_back(c.data(), c.size() / 3);
  m3c2::Tam3c2Pool pool(views, {0.0, 9.0, 10.0, 12.0});
  const std::vector<double> core{0.0, 0.0, 0.0};
  auto p = params();
  auto r = m3c2::tam3c2(p, pool, 0, {2}, {core.data(), 1});
  EXPECT_EQ(r.epochs2[0], 2u);
  const double n_plane = double(r.points2[0] - 1);
  EXPECT_NEAR(r.distance[0], (0.5 + 0.2 * n_plane) / (n_plane + 1.0), 1e-12);
  p.window_ratios = {0.05};
  r = m3c2::tam3c2(p, pool, 0, {2}, {core.data(), 1});
  EXPECT_EQ(r.points2[0], 1u);
  EXPECT_TRUE(std::isnan(r.distance[0]));
}

TEST(Tam3c2, SameBitsForAnyThreadCount) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> noise(0.0, 0.02);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  std::vector<std::vector<double>> clouds(6);
  std::vector<double> times{0.0, 1.0, 2.5, 3.0, 4.5, 7.0};
  for (int e = 0; e < 6; ++e)
    for (int k = 0; k < 300 * (e % 2 + 1); ++k) {
      const double x = u(rng), y = u(rng);
      clouds[e].insert(clouds[e].end(), {x, y, 0.1 * x + 0.05 * e + noise(rng)});
    }
  std::vector<m3c2::PointsView> views;
  for (auto& c : clouds) views.emplace_back(c.data(), c.size() / 3);
  m3c2::Tam3c2Pool pool(views, times);
  std::vector<double> core;
  for (int k = 0; k < 200; ++k) core.insert(core.end(), {u(rng) * 0.8, u(rng) * 0.8, 0.0});
  auto p = params();
  p.normal_radii = {0.3, 0.6};
  p.window_ratios = {0.3, 1.0};
  p.weights = m3c2::Tam3c2Weights::kGaussian;
  m3c2::RunOptions one, many;
  one.threads = 1, many.threads = 4;
  const auto a = m3c2::tam3c2(p, pool, 0, {1, 2, 3, 4, 5}, {core.data(), 200}, {}, {}, one);
  const auto b = m3c2::tam3c2(p, pool, 0, {1, 2, 3, 4, 5}, {core.data(), 200}, {}, {}, many);
  ASSERT_EQ(a.distance.size(), b.distance.size());
  EXPECT_EQ(0, std::memcmp(a.distance.data(), b.distance.data(), 8 * a.distance.size()));
  EXPECT_EQ(0, std::memcmp(a.lod.data(), b.lod.data(), 8 * a.lod.size()));
  std::size_t finite = 0;
  for (double d : a.distance) finite += std::isfinite(d);
  EXPECT_GT(finite, 500u);
}

TEST(Tam3c2, RefusesBadParameters) {
  std::vector<double> c = plane(3, 0.0);
  m3c2::Tam3c2Pool pool({{c.data(), 9}}, {0.0});
  const std::vector<double> core{0.0, 0.0, 0.0};
  auto p = params();
  p.window_ratios = {1.5};
  EXPECT_THROW(m3c2::tam3c2(p, pool, 0, {0}, {core.data(), 1}), m3c2::InvalidArgument);
  p = params();
  EXPECT_THROW(m3c2::tam3c2(p, pool, 1, {0}, {core.data(), 1}), m3c2::InvalidArgument);
  EXPECT_THROW(m3c2::Tam3c2Pool({{c.data(), 9}}, {NAN}), m3c2::InvalidArgument);
  p.orientation = m3c2::Vec3(0.0, 0.0, 0.0);
  EXPECT_THROW(m3c2::tam3c2(p, pool, 0, {0}, {core.data(), 1}), m3c2::InvalidArgument);
}

}  // namespace
