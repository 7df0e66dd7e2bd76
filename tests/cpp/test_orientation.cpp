// Orientation of normals (section 3.1.2): towards the closest orientation point when any are
// given (the scanner positions), otherwise along Orientation.direction.

#include "test_support.hpp"

namespace m3c2::test {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Points on a sphere (centre c, radius R) in small patches around 120 Fibonacci directions.
// Each patch is symmetric under a half turn about its radial direction u, so u is exactly an
// eigenvector of the neighbourhood covariance: the PCA normal is radial up to rounding.
// Patches are ~3 apart, so a D = 1 ball never reaches a neighbouring patch.
struct SpherePatches {
  Cloud cloud, cores;
};

SpherePatches sphere_patches(const Vec3& c, double R) {
  SpherePatches s;
  const int m = 120;
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  for (int k = 0; k < m; ++k) {
    const double z = 1.0 - 2.0 * (k + 0.5) / m;
    const double rho = std::sqrt(1.0 - z * z);
    const Vec3 u(rho * std::cos(golden * k), rho * std::sin(golden * k), z);
    const auto [e1, e2] = orthonormal_basis(u);
    for (int a = -4; a <= 4; ++a)
      for (int b = -4; b <= 4; ++b) s.cloud.add(c + R * (u + 0.01 * a * e1 + 0.01 * b * e2).normalized());
    s.cores.add(c + R * u);
  }
  return s;
}

TEST(Orientation, SphereNormalsPointToTheCentreOrientationPoint) {
  const Vec3 centre(3.0, -2.0, 1.0);
  const double R = 10.0;
  const SpherePatches s = sphere_patches(centre, R);
  Params p;
  p.normal_diameters = {1.0};
  p.orientation.points = {centre.x(), centre.y(), centre.z()};
  const NormalsResult nr = compute_normals(s.cloud.view(), s.cores.view(), p);
  for (std::size_t i = 0; i < s.cores.size(); ++i) {
    ASSERT_EQ(nr.status[i], PointStatus::kOk) << i;
    const Vec3 n = normal_at(nr.normal, i);
    const Vec3 inward = (centre - s.cores[i]) / R;
    EXPECT_GT(n.dot(centre - s.cores[i]), 0.0) << "core " << i;
    // Exact in exact arithmetic (symmetric patches); 1e-3 leaves room for any PCA solver.
    EXPECT_LT((n - inward).norm(), 1e-3) << "core " << i;
  }
}

TEST(Orientation, ComputeUsesTheSameOrientedNormals) {
  const Vec3 centre(0.0, 0.0, 0.0);
  const SpherePatches s = sphere_patches(centre, 10.0);
  Params p = basic_params(1.0, 0.3, 1.0);
  p.orientation.points = {centre.x(), centre.y(), centre.z()};
  const Result r = compute(s.cloud.view(), s.cloud.view(), s.cores.view(), p);
  for (std::size_t i = 0; i < s.cores.size(); ++i) {
    ASSERT_EQ(r.status[i], PointStatus::kOk) << i;
    EXPECT_GT(normal_at(r.normal, i).dot(centre - s.cores[i]), 0.0) << i;
    EXPECT_NEAR(r.distance[i], 0.0, 1e-12);  // a cloud compared with itself
  }
}

Cloud wall_x(double x0) {  // plane x = x0, 21 x 21 points, spacing 0.5
  return plane_grid(Vec3(x0, 0, 0), Vec3::UnitX(), 10, 0.5);
}

TEST(Orientation, WallSeenFromScannerAtMinusTenPointsToMinusX) {
  const Cloud wall = wall_x(0.0);
  const Cloud cores = wall.every_nth(13);
  Params p;
  p.normal_diameters = {2.0};
  p.orientation.points = {-10.0, 0.0, 0.0};
  const NormalsResult nr = compute_normals(wall.view(), cores.view(), p);
  for (std::size_t i = 0; i < cores.size(); ++i) {
    ASSERT_EQ(nr.status[i], PointStatus::kOk);
    EXPECT_NEAR(nr.normal[3 * i], -1.0, 1e-12) << i;
  }
  p.orientation.points = {10.0, 0.0, 0.0};
  const NormalsResult other = compute_normals(wall.view(), cores.view(), p);
  for (std::size_t i = 0; i < cores.size(); ++i) EXPECT_NEAR(other.normal[3 * i], 1.0, 1e-12) << i;
}

TEST(Orientation, EachNormalUsesItsClosestOrientationPoint) {
  // Walls at x = -5 and x = +5, scanners at x = -10 and x = +10: each wall faces its own scanner.
  Cloud walls = wall_x(-5.0);
  walls.append(wall_x(5.0));
  Cloud cores;
  cores.add(-5.0, 0.5, 0.5);
  cores.add(5.0, -1.0, 1.5);
  Params p;
  p.normal_diameters = {2.0};
  p.orientation.points = {10.0, 0.0, 0.0, -10.0, 0.0, 0.0};
  const NormalsResult nr = compute_normals(walls.view(), cores.view(), p);
  ASSERT_EQ(nr.status[0], PointStatus::kOk);
  ASSERT_EQ(nr.status[1], PointStatus::kOk);
  EXPECT_NEAR(nr.normal[0], -1.0, 1e-12);
  EXPECT_NEAR(nr.normal[3], 1.0, 1e-12);
}

TEST(Orientation, AwayFromThePointFlipsEveryNormal) {
  // CloudCompare's "+" point modes (barycentre 6, origin 8, sensor 11): n . (core - point) >= 0.
  const Vec3 centre(3.0, -2.0, 1.0);
  const SpherePatches s = sphere_patches(centre, 10.0);
  Params p;
  p.normal_diameters = {1.0};
  p.orientation.points = {centre.x(), centre.y(), centre.z()};
  p.orientation.away = true;
  const NormalsResult nr = compute_normals(s.cloud.view(), s.cores.view(), p);
  for (std::size_t i = 0; i < s.cores.size(); ++i) {
    ASSERT_EQ(nr.status[i], PointStatus::kOk) << i;
    EXPECT_GT(normal_at(nr.normal, i).dot(s.cores[i] - centre), 0.0) << "core " << i;
  }
}

TEST(Orientation, AwayWithoutPointsIsRefused) {
  const Cloud wall = wall_x(0.0);
  Params p;
  p.normal_diameters = {2.0};
  p.orientation.away = true;
  EXPECT_THROW(compute_normals(wall.view(), wall.every_nth(13).view(), p), InvalidArgument);
}

struct DirectionCase {
  const char* name;
  Vec3 plane_normal;
  Vec3 direction;
};

void PrintTo(const DirectionCase& c, std::ostream* os) { *os << c.name; }

class PreferredDirection : public ::testing::TestWithParam<DirectionCase> {};

TEST_P(PreferredDirection, NormalHasPositiveDotWithDirection) {
  const DirectionCase& dc = GetParam();
  const Vec3 n = dc.plane_normal.normalized();
  const Cloud plane = plane_grid(Vec3(1, 2, 3), n, 10, 0.5);
  const Cloud cores = plane.every_nth(17);
  Params p;
  p.normal_diameters = {2.0};
  for (int a = 0; a < 3; ++a) p.orientation.direction[a] = dc.direction[a];
  const NormalsResult nr = compute_normals(plane.view(), cores.view(), p);
  const Vec3 expected = n.dot(dc.direction) > 0 ? n : Vec3(-n);
  for (std::size_t i = 0; i < cores.size(); ++i) {
    ASSERT_EQ(nr.status[i], PointStatus::kOk);
    EXPECT_LT((normal_at(nr.normal, i) - expected).norm(), 1e-10) << i;
  }
}

INSTANTIATE_TEST_SUITE_P(AxesAndTilts, PreferredDirection,
                         ::testing::Values(DirectionCase{"plus_x", Vec3(1, 0, 0), Vec3(1, 0, 0)},
                                           DirectionCase{"minus_x", Vec3(1, 0, 0), Vec3(-1, 0, 0)},
                                           DirectionCase{"plus_y", Vec3(0, 1, 0), Vec3(0, 1, 0)},
                                           DirectionCase{"minus_y", Vec3(0, 1, 0), Vec3(0, -1, 0)},
                                           DirectionCase{"plus_z", Vec3(0, 0, 1), Vec3(0, 0, 1)},
                                           DirectionCase{"minus_z", Vec3(0, 0, 1), Vec3(0, 0, -1)},
                                           DirectionCase{"tilted_plus_z", Vec3(1, 1, 1), Vec3(0, 0, 1)},
                                           DirectionCase{"tilted_minus_z", Vec3(1, 1, 1), Vec3(0, 0, -1)},
                                           DirectionCase{"tilted_minus_x", Vec3(2, -1, 0.5), Vec3(-1, 0, 0)},
                                           DirectionCase{"unnormalised_direction", Vec3(0, 0, 1), Vec3(0, 0, -7)}),
                         [](const ::testing::TestParamInfo<DirectionCase>& info) {
                           return std::string(info.param.name);
                         });

TEST(Orientation, DefaultDirectionIsPlusZ) {
  const Cloud plane = plane_grid(Vec3::Zero(), Vec3(0.3, 0.2, -1.0), 10, 0.5);
  Cloud core;
  core.add(0, 0, 0);
  Params p;
  p.normal_diameters = {2.0};
  const NormalsResult nr = compute_normals(plane.view(), core.view(), p);
  ASSERT_EQ(nr.status[0], PointStatus::kOk);
  EXPECT_GT(nr.normal[2], 0.0);
}

}  // namespace
}  // namespace m3c2::test
