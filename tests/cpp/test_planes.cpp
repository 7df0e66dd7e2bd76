// Two parallel noise-free planes of arbitrary orientation offset by a known distance
// (sections 3.1.2-3.1.3): the distance is the offset, the normal is the plane normal oriented
// as requested, and n1 / n2 are the brute-force cylinder counts.
//
// The grid spacing is 1 and the cylinder radius 2.5, so squared in-plane distances of grid
// points to the axis are integers, at least 0.25 away from r^2 = 6.25: rounding (~1e-13)
// cannot move a point across the cylinder wall, and the brute-force count is unambiguous.

#include "test_support.hpp"

namespace m3c2::test {
namespace {

struct PlaneCase {
  const char* name;
  Vec3 normal;     // plane normal (not necessarily unit)
  Vec3 direction;  // Orientation.direction
};

void PrintTo(const PlaneCase& c, std::ostream* os) { *os << c.name; }

class ParallelPlanes : public ::testing::TestWithParam<PlaneCase> {};

TEST_P(ParallelPlanes, DistanceEqualsOffsetAndNormalIsOrientedPlaneNormal) {
  const PlaneCase& pc = GetParam();
  const Vec3 n = pc.normal.normalized();
  const Vec3 origin(12.5, -7.25, 3.0);
  const double offset = 3.7;
  const Cloud ref = plane_grid(origin, n, 20, 1.0);               // 41 x 41
  const Cloud cmp = plane_grid(origin + offset * n, n, 20, 1.0);  // same grid, shifted along n
  // Core points: reference points at least 8 from the edge (complete neighbourhoods).
  const Cloud cores = plane_grid(origin, n, 12, 1.0).every_nth(7);

  Params p = basic_params(/*D=*/10.0, /*d=*/5.0, /*max_depth=*/10.0);
  p.orientation.direction[0] = pc.direction.x();
  p.orientation.direction[1] = pc.direction.y();
  p.orientation.direction[2] = pc.direction.z();
  const Result r = compute(ref.view(), cmp.view(), cores.view(), p);
  ASSERT_EQ(r.size(), cores.size());

  // Expected orientation: the plane normal, flipped to agree with the requested direction.
  const Vec3 oriented = n.dot(pc.direction) > 0 ? n : Vec3(-n);
  const double expected_distance = offset * oriented.dot(n);
  for (std::size_t i = 0; i < cores.size(); ++i) {
    SCOPED_TRACE(::testing::Message() << pc.name << " core " << i);
    ASSERT_EQ(r.status[i], PointStatus::kOk);
    const Vec3 ni = normal_at(r.normal, i);
    EXPECT_NEAR(ni.norm(), 1.0, 1e-12);
    // Noise-free plane: PCA is exact up to rounding of ~80 coordinates of magnitude ~20.
    EXPECT_NEAR((ni - oriented).norm(), 0.0, 1e-10);
    EXPECT_NEAR(r.distance[i], expected_distance, 1e-9);
    EXPECT_NEAR(r.i1[i], 0.0, 1e-9);
    EXPECT_NEAR(r.i2[i], expected_distance, 1e-9);
    // Roughness via the smallest covariance eigenvalue is sqrt(rounding of lambda3), i.e.
    // ~sqrt(eps * lambda1) ~ 5e-8 for a noise-free plane, not ~1e-15: 1e-6 bounds that.
    EXPECT_NEAR(r.roughness[i], 0.0, 1e-6);
    EXPECT_EQ(r.normal_scale[i], 10.0);
    EXPECT_EQ(r.n1[i], brute_cylinder_count(ref, cores[i], oriented, 2.5, -10.0, 10.0));
    EXPECT_EQ(r.n2[i], brute_cylinder_count(cmp, cores[i], oriented, 2.5, -10.0, 10.0));
    EXPECT_EQ(r.n1[i], 21u);  // lattice points with i^2 + j^2 <= 6.25
    EXPECT_EQ(r.n2[i], 21u);
    // Noise-free planes: zero spread, LOD 0, a 3.7 offset is significant.
    EXPECT_NEAR(r.sigma1[i], 0.0, 1e-9);
    EXPECT_NEAR(r.lod[i], 0.0, 1e-8);
    EXPECT_EQ(r.significant[i], 1);
  }
}

const Vec3 kTilt1 = Vec3(1, 2, 3);
const Vec3 kTilt2 = Vec3(0.3, -0.5, 0.8);
const Vec3 kNearWall = Vec3(1, -2, 0.1);

INSTANTIATE_TEST_SUITE_P(Orientations, ParallelPlanes,
                         ::testing::Values(PlaneCase{"horizontal_up", Vec3(0, 0, 1), Vec3(0, 0, 1)},
                                           PlaneCase{"horizontal_down", Vec3(0, 0, 1), Vec3(0, 0, -1)},
                                           PlaneCase{"wall_x_plus", Vec3(1, 0, 0), Vec3(1, 0, 0)},
                                           PlaneCase{"wall_x_minus", Vec3(1, 0, 0), Vec3(-1, 0, 0)},
                                           PlaneCase{"wall_y_plus", Vec3(0, 1, 0), Vec3(0, 1, 0)},
                                           PlaneCase{"wall_diagonal", Vec3(1, 1, 0), Vec3(-1, 0, 0)},
                                           PlaneCase{"tilted_123", kTilt1, Vec3(0, 0, 1)},
                                           PlaneCase{"tilted_123_flipped", kTilt1, Vec3(0, 0, -1)},
                                           PlaneCase{"tilted_mixed", kTilt2, Vec3(0, 1, 0)},
                                           PlaneCase{"near_vertical_wall", kNearWall, Vec3(1, 0, 0)},
                                           PlaneCase{"overhang", Vec3(0.2, 0.1, -1), Vec3(0, 0, -1)}),
                         [](const ::testing::TestParamInfo<PlaneCase>& info) { return std::string(info.param.name); });

TEST(Planes, SignOfDistanceFollowsOrientedNormal) {
  // Compared plane BELOW the reference: negative distance with +Z, positive with -Z.
  const Vec3 n(0, 0, 1);
  const Cloud ref = plane_grid(Vec3(0, 0, 0), n, 15, 1.0);
  const Cloud cmp = plane_grid(Vec3(0, 0, -0.8), n, 15, 1.0);
  Cloud cores;
  cores.add(0, 0, 0);
  cores.add(3, -2, 0);
  Params p = basic_params(8.0, 5.0, 5.0);
  const Result up = compute(ref.view(), cmp.view(), cores.view(), p);
  p.orientation.direction[2] = -1.0;
  const Result down = compute(ref.view(), cmp.view(), cores.view(), p);
  for (std::size_t i = 0; i < cores.size(); ++i) {
    EXPECT_NEAR(up.distance[i], -0.8, 1e-12);
    EXPECT_NEAR(down.distance[i], 0.8, 1e-12);
    EXPECT_NEAR(up.normal[3 * i + 2], 1.0, 1e-12);
    EXPECT_NEAR(down.normal[3 * i + 2], -1.0, 1e-12);
  }
}

TEST(Planes, CorePointsOffThePlaneMeasureFromTheCorePoint) {
  // i1 and i2 are positions along the normal from the core point: a core point 0.5 above the
  // reference plane sees i1 = -0.5, i2 = offset - 0.5, distance = offset.
  const Vec3 n = Vec3(1, 2, 3).normalized();
  const Cloud ref = plane_grid(Vec3::Zero(), n, 15, 1.0);
  const Cloud cmp = plane_grid(2.0 * n, n, 15, 1.0);
  Cloud cores;
  cores.add(0.5 * n);
  Params p = basic_params(8.0, 5.0, 5.0);
  const Result r = compute(ref.view(), cmp.view(), cores.view(), p);
  ASSERT_EQ(r.status[0], PointStatus::kOk);
  EXPECT_NEAR(r.i1[0], -0.5, 1e-10);
  EXPECT_NEAR(r.i2[0], 1.5, 1e-10);
  EXPECT_NEAR(r.distance[0], 2.0, 1e-10);
}

}  // namespace
}  // namespace m3c2::test
