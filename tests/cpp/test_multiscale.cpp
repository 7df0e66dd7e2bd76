// Multi-scale normals (section 3.2): the most planar scale is chosen among those with at least
// min_points_multiscale neighbours; roughness sigma(D) (sections 3.1.2, 5.1).

#include "test_support.hpp"

#include <set>

namespace m3c2::test {
namespace {

constexpr double kPi = 3.14159265358979323846;

TEST(Multiscale, SmallScaleFollowsCorrugationWhenItIsMostPlanar) {
  // z = A sin(2 pi x / lambda), lambda = 10, A = 1, grid spacing 0.1. Core points at the
  // inflection points (z = 0, slope A k = 0.628). At D = 1 the surface is locally a plane
  // (cubic deviation A k^3 x^3 / 6 < 0.006 over the ball); at D = 20 the ball holds two
  // wavelengths and a slab 2A thick, far less planar.
  const double lambda = 10.0, A = 1.0, k = 2 * kPi / lambda;
  const Cloud cloud = height_grid(0.0, 0.0, 401, 101, 0.1, [&](double x, double) { return A * std::sin(k * x); });
  Cloud cores;
  for (double x : {10.0, 15.0, 20.0, 25.0, 30.0}) cores.add(x, 5.0, A * std::sin(k * x));
  Params p;
  p.normal_diameters = {1.0, 20.0};
  const NormalsResult nr = compute_normals(cloud.view(), cores.view(), p);
  for (std::size_t i = 0; i < cores.size(); ++i) {
    ASSERT_EQ(nr.status[i], PointStatus::kOk) << i;
    EXPECT_EQ(nr.normal_scale[i], 1.0) << i;
    const double slope = A * k * std::cos(k * cores[i].x());
    const Vec3 expected = Vec3(-slope, 0, 1).normalized();
    // The cubic term biases the fitted slope by < 1 % of 0.63 (< 0.4 degree): 0.01 in vector norm.
    EXPECT_LT((normal_at(nr.normal, i) - expected).norm(), 0.01) << i;
  }
}

TEST(Multiscale, LargeScaleChosenOnNoisyPlaneAndSeesTheMeanPlane) {
  // Flat plane, spacing 0.1, Gaussian z noise sigma 0.1 (as large as the spacing). At D = 0.4
  // (~12 points) the neighbourhood is an isotropic blob; at D = 4 it is a thin disc.
  std::mt19937_64 rng(5);
  std::normal_distribution<double> g(0.0, 0.1);
  const Cloud cloud = height_grid(0.0, 0.0, 101, 101, 0.1, [&](double, double) { return g(rng); });
  const Cloud cores = random_box(6, 50, Vec3(3, 3, 0), Vec3(7, 7, 0));
  Params p;
  p.normal_diameters = {0.4, 4.0};
  const NormalsResult nr = compute_normals(cloud.view(), cores.view(), p);
  for (std::size_t i = 0; i < cores.size(); ++i) {
    ASSERT_EQ(nr.status[i], PointStatus::kOk) << i;
    EXPECT_EQ(nr.normal_scale[i], 4.0) << i;
    // ~1250 points over a radius of 2 with noise 0.1: slope error ~ 0.1 / (1 * sqrt(1250)) = 0.003.
    EXPECT_GT(nr.normal[3 * i + 2], 0.995) << i;
    // Roughness at the chosen scale is the noise level (sampling error ~2 %).
    EXPECT_NEAR(nr.roughness[i], 0.1, 0.01) << i;
  }
}

// Core point at the origin. `small` coplanar points (z = 0) at radius 0.08: the only ones in
// the D = 0.2 ball, perfectly planar. 40 points at radius 0.2-0.45 with z = +-0.01: D = 1 is
// nearly planar. 200 points at radius 0.6-1.9 with z = +-0.3: D = 4 is the least planar.
Cloud min_points_scene(int small) {
  Cloud c;
  for (int j = 0; j < small; ++j) {
    const double a = 2 * kPi * j / small;
    c.add(0.08 * std::cos(a), 0.08 * std::sin(a), 0.0);
  }
  for (int j = 0; j < 40; ++j) {
    const double a = 2 * kPi * j / 40 + 0.1, rho = 0.2 + 0.25 * ((j * 7) % 40) / 40.0;
    c.add(rho * std::cos(a), rho * std::sin(a), (j % 2 ? 0.01 : -0.01));
  }
  for (int j = 0; j < 200; ++j) {
    const double a = 2 * kPi * j / 200 + 0.05, rho = 0.6 + 1.3 * ((j * 37) % 200) / 200.0;
    c.add(rho * std::cos(a), rho * std::sin(a), (j % 2 ? 0.3 : -0.3));
  }
  return c;
}

NormalsResult origin_normals(const Cloud& cloud, const std::vector<double>& diameters,
                             std::uint32_t min_multiscale = 10) {
  Cloud core;
  core.add(0, 0, 0);
  Params p;
  p.normal_diameters = diameters;
  p.min_points_multiscale = min_multiscale;
  return compute_normals(cloud.view(), core.view(), p);
}

TEST(Multiscale, ScaleWithNinePointsIsNeverChosen) {
  const NormalsResult nr = origin_normals(min_points_scene(9), {0.2, 1.0, 4.0});
  ASSERT_EQ(nr.status[0], PointStatus::kOk);
  EXPECT_EQ(nr.normal_scale[0], 1.0);
  EXPECT_EQ(nr.count[0], 9u + 40u);
}

TEST(Multiscale, ScaleWithExactlyTenPointsCanBeChosen) {
  const NormalsResult nr = origin_normals(min_points_scene(10), {0.2, 1.0, 4.0});
  ASSERT_EQ(nr.status[0], PointStatus::kOk);
  EXPECT_EQ(nr.normal_scale[0], 0.2);
  EXPECT_EQ(nr.count[0], 10u);
  EXPECT_NEAR(std::abs(nr.normal[2]), 1.0, 1e-12);
}

TEST(Multiscale, MinPointsMultiscaleIsConfigurable) {
  const NormalsResult nr = origin_normals(min_points_scene(9), {0.2, 1.0, 4.0}, /*min=*/5);
  ASSERT_EQ(nr.status[0], PointStatus::kOk);
  EXPECT_EQ(nr.normal_scale[0], 0.2);
  EXPECT_EQ(nr.count[0], 9u);
}

TEST(Multiscale, TooFewNormalPointsWhenNoScaleHasTen) {
  Cloud c;  // nine coplanar points within 0.08 of the origin, nothing else
  for (int j = 0; j < 9; ++j) c.add(0.08 * std::cos(0.7 * j), 0.08 * std::sin(0.7 * j), 0.0);
  const NormalsResult nr = origin_normals(c, {0.2, 1.0, 4.0});
  EXPECT_EQ(nr.status[0], PointStatus::kTooFewNormalPoints);
  EXPECT_TRUE(std::isnan(nr.normal[0]) && std::isnan(nr.normal[1]) && std::isnan(nr.normal[2]));
}

TEST(Multiscale, SingleScaleNeedsOnlyMinPointsNormal) {
  Cloud c;
  for (int j = 0; j < 9; ++j) c.add(0.08 * std::cos(0.7 * j), 0.08 * std::sin(0.7 * j), 0.0);
  const NormalsResult nr = origin_normals(c, {0.2});
  EXPECT_EQ(nr.status[0], PointStatus::kOk);
  EXPECT_EQ(nr.count[0], 9u);
}

TEST(Multiscale, ChosenScaleGivesSameResultAsThatScaleAlone) {
  // No leakage between scales: where a multi-scale run picks D_k, a run with {D_k} alone must
  // see the very same neighbours (identical count) and give the same normal and roughness. The
  // two runs index the cloud on different grids (the octree's cell follows the smallest
  // diameter), so their sums are folded in a different order and the values agree to rounding:
  // 1e-11 on unit normals, 1e-9 relative on roughness (a square root of a small eigenvalue,
  // which amplifies rounding). On one grid they are the same bits (test_octree.cpp).
  const Pair pr = rough_pair(2718, 8000, 10.0, 0.05, 0.0);
  const std::vector<double> scales = {0.3, 0.6, 1.2, 2.4};
  Params p;
  p.normal_diameters = scales;
  const NormalsResult multi = compute_normals(pr.reference.view(), pr.cores.view(), p);
  std::set<double> chosen;
  for (double D : scales) {
    Params single;
    single.normal_diameters = {D};
    const NormalsResult one = compute_normals(pr.reference.view(), pr.cores.view(), single);
    for (std::size_t i = 0; i < pr.cores.size(); ++i) {
      if (multi.status[i] != PointStatus::kOk || multi.normal_scale[i] != D) continue;
      chosen.insert(D);
      ASSERT_EQ(one.status[i], PointStatus::kOk) << "core " << i << " D " << D;
      for (int a = 0; a < 3; ++a)
        EXPECT_NEAR(multi.normal[3 * i + a], one.normal[3 * i + a], 1e-11) << "core " << i << " D " << D;
      EXPECT_NEAR(multi.roughness[i], one.roughness[i], 1e-9 * one.roughness[i]) << "core " << i << " D " << D;
      EXPECT_EQ(multi.count[i], one.count[i]) << "core " << i << " D " << D;
    }
  }
  EXPECT_GE(chosen.size(), 2u) << "scene must make the rule pick more than one scale";
}

TEST(Roughness, TwoLayerSlabHasRoughnessHalfItsThickness) {
  // Each grid (x, y) carries z = +a and z = -a: the best-fit plane is z = 0 and every point is
  // at distance a from it. Population spread = a; sample spread = a sqrt(n / (n - 1)).
  const double a = 0.02;
  Cloud c;
  for (int i = -10; i <= 10; ++i)
    for (int j = -10; j <= 10; ++j) {
      c.add(0.1 * i, 0.1 * j, a);
      c.add(0.1 * i, 0.1 * j, -a);
    }
  Cloud core;
  core.add(0, 0, 0);
  Params p;
  p.normal_diameters = {1.0};
  p.variance = Variance::kPopulation;
  const NormalsResult pop = compute_normals(c.view(), core.view(), p);
  p.variance = Variance::kSample;
  const NormalsResult smp = compute_normals(c.view(), core.view(), p);
  ASSERT_EQ(pop.status[0], PointStatus::kOk);
  const auto n = static_cast<double>(pop.count[0]);
  EXPECT_EQ(pop.count[0], brute_ball_count(c, Vec3::Zero(), 0.5));
  EXPECT_NEAR(pop.roughness[0], a, 1e-12);
  EXPECT_NEAR(smp.roughness[0], a * std::sqrt(n / (n - 1)), 1e-12);
  EXPECT_NEAR(std::abs(pop.normal[2]), 1.0, 1e-12);
}

TEST(Roughness, ByScaleMatchesSingleScaleNormalsAndIsNaNBelowMinPoints) {
  const Pair pr = rough_pair(31, 4000, 10.0, 0.05, 0.0);
  const std::vector<double> scales = {0.1, 0.5, 1.5};
  const std::uint32_t min_points = 5;
  const std::vector<double> rb =
      roughness_by_scale(pr.reference.view(), pr.cores.view(), scales, Variance::kSample, min_points);
  ASSERT_EQ(rb.size(), pr.cores.size() * scales.size());
  std::size_t nan_seen = 0;
  for (std::size_t s = 0; s < scales.size(); ++s) {
    Params p;
    p.normal_diameters = {scales[s]};
    p.min_points_normal = min_points;
    const NormalsResult nr = compute_normals(pr.reference.view(), pr.cores.view(), p);
    for (std::size_t i = 0; i < pr.cores.size(); ++i) {
      const double v = rb[i * scales.size() + s];
      const std::uint32_t count = brute_ball_count(pr.reference, pr.cores[i], scales[s] / 2);
      if (count < min_points) {
        EXPECT_TRUE(std::isnan(v)) << "core " << i << " D " << scales[s] << " count " << count;
        ++nan_seen;
      } else if (nr.status[i] == PointStatus::kOk) {
        // Same quantity computed by two entry points: allow rounding differences only.
        EXPECT_NEAR(v, nr.roughness[i], 1e-12) << "core " << i << " D " << scales[s];
      }
    }
  }
  EXPECT_GT(nan_seen, 0u);  // D = 0.1 around 4000 points on 100 m^2 often has < 5 neighbours
}

}  // namespace
}  // namespace m3c2::test
