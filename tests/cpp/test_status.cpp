// Per-core-point failures are NaN plus a PointStatus (never a made-up 0), and caller mistakes
// throw InvalidArgument.

#include "test_support.hpp"

#include <set>
#include <string>

namespace m3c2::test {
namespace {

// Horizontal grid z = z0, 21 x 21, spacing 0.1, centred on the origin; points with
// x^2 + y^2 < hole^2 removed.
Cloud flat(double z0, double hole = 0.0) {
  Cloud c;
  for (int i = -10; i <= 10; ++i)
    for (int j = -10; j <= 10; ++j) {
      const double x = 0.1 * i, y = 0.1 * j;
      if (x * x + y * y < hole * hole) continue;
      c.add(x, y, z0);
    }
  return c;
}

Cloud origin() {
  Cloud c;
  c.add(0, 0, 0);
  return c;
}

// D = 1 (radius 0.5), d = 0.25 (radius 0.125, no grid point near the wall), max_depth 1.
Params status_params() { return basic_params(1.0, 0.25, 1.0); }

void expect_no_distance(const Result& r, std::size_t i) {
  EXPECT_TRUE(std::isnan(r.distance[i])) << "distance " << r.distance[i];
  EXPECT_TRUE(std::isnan(r.lod[i])) << "lod " << r.lod[i];
  EXPECT_EQ(r.significant[i], 0);
}

void expect_no_normal(const Result& r, std::size_t i) {
  for (int a = 0; a < 3; ++a) EXPECT_TRUE(std::isnan(r.normal[3 * i + a])) << "normal[" << a << "]";
  EXPECT_EQ(r.n1[i], 0u);  // no cylinder searched
  EXPECT_EQ(r.n2[i], 0u);
  EXPECT_TRUE(std::isnan(r.i1[i]));
  EXPECT_TRUE(std::isnan(r.i2[i]));
  EXPECT_TRUE(std::isnan(r.sigma1[i]));
  EXPECT_TRUE(std::isnan(r.sigma2[i]));
}

TEST(Status, IsolatedCorePointHasTooFewNormalPoints) {
  const Cloud ref = flat(0.0), cmp = flat(0.3);
  Cloud core;
  core.add(50.0, 50.0, 0.0);
  const Result r = compute(ref.view(), cmp.view(), core.view(), status_params());
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r.status[0], PointStatus::kTooFewNormalPoints);
  expect_no_distance(r, 0);
  expect_no_normal(r, 0);
  EXPECT_TRUE(std::isnan(r.roughness[0]));
}

TEST(Status, TwoNeighboursAreTooFewForAPlane) {
  Cloud ref;
  ref.add(0.1, 0, 0);
  ref.add(0, 0.1, 0);
  const Cloud cmp = flat(0.3);
  const Result r = compute(ref.view(), cmp.view(), origin().view(), status_params());
  EXPECT_EQ(r.status[0], PointStatus::kTooFewNormalPoints);
  expect_no_distance(r, 0);
}

TEST(Status, CollinearNeighboursGiveDegenerateNormal) {
  Cloud line;
  for (int k = -20; k <= 20; ++k) line.add(0.01 * k, 0.0, 0.0);
  const Cloud cmp = flat(0.3);
  const Result r = compute(line.view(), cmp.view(), origin().view(), status_params());
  EXPECT_EQ(r.status[0], PointStatus::kDegenerateNormal);
  expect_no_distance(r, 0);
  expect_no_normal(r, 0);
}

TEST(Status, TiltedCollinearNeighboursGiveDegenerateNormal) {
  Cloud line;
  const Vec3 dir = Vec3(1, 2, -0.5).normalized();
  for (int k = -20; k <= 20; ++k) line.add(Vec3(0.3, 0.1, 0.2) + 0.013 * k * dir);
  Cloud core;
  core.add(0.3, 0.1, 0.2);
  const Result r = compute(line.view(), flat(0.3).view(), core.view(), status_params());
  EXPECT_EQ(r.status[0], PointStatus::kDegenerateNormal);
  expect_no_distance(r, 0);
}

TEST(Status, CoincidentNeighboursGiveDegenerateNormal) {
  Cloud same;
  for (int k = 0; k < 12; ++k) same.add(0.05, 0.05, 0.0);
  const Result r = compute(same.view(), flat(0.3).view(), origin().view(), status_params());
  EXPECT_EQ(r.status[0], PointStatus::kDegenerateNormal);
  expect_no_distance(r, 0);
}

TEST(Status, HoleInReferenceGivesEmptyCylinder1) {
  const Cloud ref = flat(0.0, /*hole=*/0.25), cmp = flat(0.3);
  const Result r = compute(ref.view(), cmp.view(), origin().view(), status_params());
  EXPECT_EQ(r.status[0], PointStatus::kEmptyCylinder1);
  expect_no_distance(r, 0);
  EXPECT_EQ(r.n1[0], 0u);
  EXPECT_EQ(r.n2[0], brute_cylinder_count(cmp, Vec3::Zero(), Vec3::UnitZ(), 0.125, -1, 1));
  EXPECT_GT(r.n2[0], 0u);
  EXPECT_TRUE(std::isnan(r.i1[0]));
  EXPECT_TRUE(std::isnan(r.sigma1[0]));
  EXPECT_NEAR(r.normal[2], 1.0, 1e-12);  // the normal itself was computed
}

TEST(Status, HoleInComparedGivesEmptyCylinder2) {
  const Cloud ref = flat(0.0), cmp = flat(0.3, /*hole=*/0.25);
  const Result r = compute(ref.view(), cmp.view(), origin().view(), status_params());
  EXPECT_EQ(r.status[0], PointStatus::kEmptyCylinder2);
  expect_no_distance(r, 0);
  EXPECT_EQ(r.n2[0], 0u);
  EXPECT_EQ(r.n1[0], brute_cylinder_count(ref, Vec3::Zero(), Vec3::UnitZ(), 0.125, -1, 1));
  EXPECT_TRUE(std::isnan(r.i2[0]));
  EXPECT_TRUE(std::isnan(r.sigma2[0]));
  EXPECT_NEAR(r.normal[2], 1.0, 1e-12);
}

TEST(Status, ComparedBeyondMaxDepthGivesEmptyCylinder2) {
  const Cloud ref = flat(0.0), cmp = flat(1.5);  // max_depth is 1
  const Result r = compute(ref.view(), cmp.view(), origin().view(), status_params());
  EXPECT_EQ(r.status[0], PointStatus::kEmptyCylinder2);
  expect_no_distance(r, 0);
}

// Compared cloud: a plane at z = 0.3 with a hole of radius 0.25, plus `k` points inside the
// cylinder at z = 0.3 + small offsets.
Cloud compared_with_k_in_cylinder(int k) {
  Cloud c = flat(0.3, 0.25);
  for (int j = 0; j < k; ++j) c.add(0.02 * j, -0.01 * j, 0.3 + 0.01 * (j % 2));
  return c;
}

TEST(Status, TwoPointsInCylinderGiveDistanceButNoLod) {
  const Cloud ref = flat(0.0);
  const Cloud cmp = compared_with_k_in_cylinder(2);
  const Result r = compute(ref.view(), cmp.view(), origin().view(), status_params());
  EXPECT_EQ(r.status[0], PointStatus::kTooFewPointsForLod);
  EXPECT_EQ(r.n2[0], 2u);
  EXPECT_NEAR(r.distance[0], 0.305, 1e-12);
  EXPECT_TRUE(std::isnan(r.lod[0]));
  EXPECT_EQ(r.significant[0], 0);  // 0.305 would exceed any LOD, but n2 < min_points
}

TEST(Status, OnePointInCylinderHasUndefinedSampleSpread) {
  const Cloud cmp = compared_with_k_in_cylinder(1);
  const Result r = compute(flat(0.0).view(), cmp.view(), origin().view(), status_params());
  EXPECT_EQ(r.status[0], PointStatus::kTooFewPointsForLod);
  EXPECT_NEAR(r.distance[0], 0.3, 1e-12);
  EXPECT_TRUE(std::isnan(r.sigma2[0])) << r.sigma2[0];
  EXPECT_TRUE(std::isnan(r.lod[0]));
  EXPECT_EQ(r.significant[0], 0);
}

TEST(Status, MinPointsBoundaryIsInclusive) {
  // n2 = 3 < 4: no LOD; n2 = 4: LOD computed.
  const Cloud ref = flat(0.0);
  const Result r3 = compute(ref.view(), compared_with_k_in_cylinder(3).view(), origin().view(), status_params());
  EXPECT_EQ(r3.status[0], PointStatus::kTooFewPointsForLod);
  EXPECT_TRUE(std::isnan(r3.lod[0]));
  const Result r4 = compute(ref.view(), compared_with_k_in_cylinder(4).view(), origin().view(), status_params());
  EXPECT_EQ(r4.status[0], PointStatus::kOk);
  EXPECT_EQ(r4.n2[0], 4u);
  EXPECT_TRUE(std::isfinite(r4.lod[0]));
  EXPECT_EQ(r4.significant[0], 1);
}

TEST(Status, CallerNormalsZeroOrNaNAreDegenerate) {
  const Cloud ref = flat(0.0), cmp = flat(0.3);
  Cloud cores;
  cores.add(0, 0, 0);
  cores.add(0.2, 0.2, 0);
  cores.add(-0.2, 0.1, 0);
  cores.add(0.1, -0.3, 0);
  Params p = status_params();
  p.normal_source = NormalSource::kCorePoints;
  const std::vector<double> normals = {0, 0, 1, 0, 0, 0, kNaN, 0, 1, 0, 0, -1};
  const Result r = compute(ref.view(), cmp.view(), cores.view(), p, {}, normals);
  EXPECT_EQ(r.status[0], PointStatus::kOk);
  EXPECT_NEAR(r.distance[0], 0.3, 1e-12);
  EXPECT_EQ(r.status[1], PointStatus::kDegenerateNormal);
  expect_no_distance(r, 1);
  EXPECT_EQ(r.status[2], PointStatus::kDegenerateNormal);
  expect_no_distance(r, 2);
  EXPECT_EQ(r.status[3], PointStatus::kOk);
  // Whether a caller's normal is re-oriented is not specified: only the magnitude is checked.
  EXPECT_NEAR(std::abs(r.distance[3]), 0.3, 1e-12);
}

TEST(Status, StatusNamesAreNonEmptyAndDistinct) {
  std::set<std::string> names;
  for (int s = 0; s <= 5; ++s) {
    const std::string_view name = status_name(static_cast<PointStatus>(s));
    EXPECT_FALSE(name.empty()) << s;
    names.emplace(name);
  }
  EXPECT_EQ(names.size(), 6u);
}

TEST(Status, StatusValuesArePartOfTheFileFormat) {
  EXPECT_EQ(static_cast<int>(PointStatus::kOk), 0);
  EXPECT_EQ(static_cast<int>(PointStatus::kTooFewNormalPoints), 1);
  EXPECT_EQ(static_cast<int>(PointStatus::kDegenerateNormal), 2);
  EXPECT_EQ(static_cast<int>(PointStatus::kEmptyCylinder1), 3);
  EXPECT_EQ(static_cast<int>(PointStatus::kEmptyCylinder2), 4);
  EXPECT_EQ(static_cast<int>(PointStatus::kTooFewPointsForLod), 5);
}

// --- InvalidArgument ---------------------------------------------------------------------

class BadParams : public ::testing::Test {
 protected:
  Cloud ref = flat(0.0), cmp = flat(0.3), core = origin();
  void expect_invalid(const Params& p, const std::vector<double>& normals = {}) {
    EXPECT_THROW(compute(ref.view(), cmp.view(), core.view(), p, {}, normals), InvalidArgument);
  }
};

TEST_F(BadParams, ValidParamsDoNotThrow) {
  EXPECT_NO_THROW(compute(ref.view(), cmp.view(), core.view(), status_params()));
}

TEST_F(BadParams, EmptyNormalDiameters) {
  Params p = status_params();
  p.normal_diameters.clear();
  expect_invalid(p);
  EXPECT_THROW(compute_normals(ref.view(), core.view(), p), InvalidArgument);
}

TEST_F(BadParams, NonPositiveOrNaNNormalDiameter) {
  for (double D : {0.0, -1.0, kNaN}) {
    Params p = status_params();
    p.normal_diameters = {0.5, D};
    expect_invalid(p);
    EXPECT_THROW(compute_normals(ref.view(), core.view(), p), InvalidArgument) << D;
  }
}

TEST_F(BadParams, NonPositiveOrNaNProjectionDiameter) {
  for (double d : {0.0, -0.2, kNaN}) {
    Params p = status_params();
    p.projection_diameter = d;
    expect_invalid(p);
  }
}

TEST_F(BadParams, NonPositiveOrNaNMaxDepth) {
  for (double L : {0.0, -1.0, kNaN}) {
    Params p = status_params();
    p.max_depth = L;
    expect_invalid(p);
  }
}

TEST_F(BadParams, ConfidenceOutsideOpenUnitInterval) {
  for (double c : {0.0, 1.0, -0.5, 1.5, kNaN}) {
    Params p = status_params();
    p.confidence = c;
    expect_invalid(p);
  }
}

TEST_F(BadParams, ZeroMinPoints) {
  Params p = status_params();
  p.min_points = 0;
  expect_invalid(p);
}

TEST_F(BadParams, WrongCoreNormalsSize) {
  Params p = status_params();
  p.normal_source = NormalSource::kCorePoints;
  expect_invalid(p, {});
  expect_invalid(p, {0, 0});
  expect_invalid(p, {0, 0, 1, 0, 0, 1});
  EXPECT_NO_THROW(compute(ref.view(), cmp.view(), core.view(), p, {}, {0, 0, 1}));
}

TEST_F(BadParams, NaNCoordinatesInAnyInput) {
  const Params p = status_params();
  Cloud bad_ref = ref, bad_cmp = cmp, bad_core = core;
  bad_ref.xyz[3 * 7 + 1] = kNaN;
  bad_cmp.xyz[3 * 100 + 2] = kNaN;
  bad_core.xyz[0] = kNaN;
  EXPECT_THROW(compute(bad_ref.view(), cmp.view(), core.view(), p), InvalidArgument);
  EXPECT_THROW(compute(ref.view(), bad_cmp.view(), core.view(), p), InvalidArgument);
  EXPECT_THROW(compute(ref.view(), cmp.view(), bad_core.view(), p), InvalidArgument);
  EXPECT_THROW(compute_normals(bad_ref.view(), core.view(), p), InvalidArgument);
  EXPECT_THROW(compute_normals(ref.view(), bad_core.view(), p), InvalidArgument);
}

}  // namespace
}  // namespace m3c2::test
