// docs/errors.md at the engine level: empty and non-finite inputs throw InvalidArgument with the
// documented message; clouds of 1-2 points, duplicated points, exactly planar clouds, core
// points far outside (even near the float64 limit) and cylinders of more than 65,535 points are
// per-core-point statuses and exact counts, never crashes. Run under ASan/UBSan in
// scripts/test.sh (build/asan).

#include "test_support.hpp"

#include <limits>
#include <string>

namespace m3c2::test {
namespace {

Cloud square(double z0, int half = 10, double spacing = 0.125) {
  Cloud c;
  for (int i = -half; i <= half; ++i)
    for (int j = -half; j <= half; ++j) c.add(spacing * i, spacing * j, z0);
  return c;
}

Cloud single(double x, double y, double z) {
  Cloud c;
  c.add(x, y, z);
  return c;
}

Params vertical_params(double d, double max_depth) {
  Params p;
  p.normal_source = NormalSource::kVertical;
  p.projection_diameter = d;
  p.max_depth = max_depth;
  return p;
}

std::string invalid_argument_message(const Cloud& ref, const Cloud& cmp, const Cloud& core) {
  try {
    compute(ref.view(), cmp.view(), core.view(), basic_params(1.0, 0.5, 1.0));
  } catch (const InvalidArgument& e) {
    return e.what();
  }
  return "(no exception)";
}

TEST(ErrorsEdgeCases, EmptyCloudsThrowInvalidArgument) {
  const Cloud empty, plane = square(0.0), core = single(0, 0, 0);
  EXPECT_EQ(invalid_argument_message(empty, plane, core), "the reference cloud is empty");
  EXPECT_EQ(invalid_argument_message(plane, empty, core), "the compared cloud is empty");
}

TEST(ErrorsEdgeCases, NoCorePointsGiveAnEmptyResult) {
  const Cloud plane = square(0.0), none;
  const Result r = compute(plane.view(), plane.view(), none.view(), basic_params(1.0, 0.5, 1.0));
  EXPECT_EQ(r.size(), 0u);
}

TEST(ErrorsEdgeCases, NonFiniteCoordinatesAreCountedInTheMessage) {
  Cloud bad = square(0.0);
  bad.xyz[2] = kNaN;
  bad.xyz[4] = std::numeric_limits<double>::infinity();
  bad.xyz[9] = -std::numeric_limits<double>::infinity();
  const Cloud plane = square(0.1), core = single(0, 0, 0);
  EXPECT_EQ(invalid_argument_message(bad, plane, core), "reference cloud has 3 non-finite coordinates (NaN or Inf)");
  EXPECT_EQ(invalid_argument_message(plane, bad, core), "compared cloud has 3 non-finite coordinates (NaN or Inf)");
  EXPECT_EQ(invalid_argument_message(plane, plane, bad), "core points has 3 non-finite coordinates (NaN or Inf)");
}

TEST(ErrorsEdgeCases, OneAndTwoPointCloudsGiveStatusesNotErrors) {
  const Cloud plane = square(0.0), core = single(0, 0, 0);
  for (const int n : {1, 2}) {
    Cloud few;
    for (int k = 0; k < n; ++k) few.add(0.01 * k, 0.0, 0.0);
    // Too few points for a plane fit: status 1, everything NaN.
    Result r = compute(few.view(), plane.view(), core.view(), basic_params(1.0, 0.5, 1.0));
    EXPECT_EQ(r.status[0], PointStatus::kTooFewNormalPoints) << n;
    EXPECT_TRUE(std::isnan(r.distance[0]));
    // With imposed vertical normals a distance exists but no LOD (n < min_points, and n = 1 has no spread).
    Cloud few_up;
    for (int k = 0; k < n; ++k) few_up.add(0.01 * k, 0.0, 0.25);
    r = compute(few.view(), few_up.view(), core.view(), vertical_params(0.5, 1.0));
    EXPECT_EQ(r.status[0], PointStatus::kTooFewPointsForLod) << n;
    EXPECT_EQ(r.n1[0], static_cast<std::uint32_t>(n));
    EXPECT_EQ(r.distance[0], 0.25);
    EXPECT_TRUE(std::isnan(r.lod[0]));
    EXPECT_EQ(r.significant[0], 0);
    // min_points 1: n = 2 has a (zero) spread and a LOD; n = 1 still has none.
    Params p = vertical_params(0.5, 1.0);
    p.min_points = 1;
    r = compute(few.view(), few_up.view(), core.view(), p);
    EXPECT_EQ(r.status[0], n == 2 ? PointStatus::kOk : PointStatus::kTooFewPointsForLod) << n;
  }
}

TEST(ErrorsEdgeCases, DuplicatedPointsCountTwiceAndKeepTheDistance) {
  const Pair pair = rough_pair(3, 3000, 6.0);
  Cloud ref2 = pair.reference, cmp2 = pair.compared;
  ref2.append(pair.reference);
  cmp2.append(pair.compared);
  const Cloud core = pair.reference.every_nth(97);
  const Params p = basic_params(1.0, 0.6, 1.0);
  const Result once = compute(pair.reference.view(), pair.compared.view(), core.view(), p);
  const Result twice = compute(ref2.view(), cmp2.view(), core.view(), p);
  ASSERT_EQ(once.size(), twice.size());
  for (std::size_t i = 0; i < once.size(); ++i) {
    EXPECT_EQ(twice.n1[i], 2 * once.n1[i]) << i;
    EXPECT_EQ(twice.n2[i], 2 * once.n2[i]) << i;
    EXPECT_EQ(twice.status[i], once.status[i]) << i;
    if (!std::isnan(once.distance[i])) {
      EXPECT_NEAR(twice.distance[i], once.distance[i], 1e-12) << i;
    }
  }
}

TEST(ErrorsEdgeCases, ExactlyPlanarCloudsWithBinaryChangeHaveZeroSpread) {
  const Cloud ref = square(0.0), cmp = square(0.125), core = square(0.0, 2);
  Params p = vertical_params(0.5, 0.5);
  p.registration_error = 0.0;
  Result r = compute(ref.view(), cmp.view(), core.view(), p);
  for (std::size_t i = 0; i < r.size(); ++i) {
    EXPECT_EQ(r.status[i], PointStatus::kOk);
    EXPECT_EQ(r.sigma1[i], 0.0);
    EXPECT_EQ(r.sigma2[i], 0.0);
    EXPECT_EQ(r.distance[i], 0.125);
    EXPECT_EQ(r.lod[i], 0.0);        // LOD = z * reg = 0
    EXPECT_EQ(r.significant[i], 1);  // any non-zero change is significant
  }
  r = compute(ref.view(), ref.view(), core.view(), p);
  for (std::size_t i = 0; i < r.size(); ++i) {
    EXPECT_EQ(r.distance[i], 0.0);
    EXPECT_EQ(r.significant[i], 0);  // |0| > 0 is false
  }
  p.registration_error = 0.07;  // LOD = 1.96 * 0.07 > 0.125
  r = compute(ref.view(), cmp.view(), core.view(), p);
  for (std::size_t i = 0; i < r.size(); ++i) {
    EXPECT_DOUBLE_EQ(r.lod[i], 1.959963984540054 * 0.07);
    EXPECT_EQ(r.significant[i], 0);
  }
}

TEST(ErrorsEdgeCases, CorePointsFarOutsideOrNearTheFloatLimit) {
  const Cloud ref = square(0.0), cmp = square(0.125);
  const double big = std::numeric_limits<double>::max() / 4;
  Cloud core;
  core.add(1e6, 1e6, 0.0);
  core.add(0.0, 0.0, 1e300);
  core.add(-big, big, -big);
  core.add(0.0, 0.0, 0.0);
  Result r = compute(ref.view(), cmp.view(), core.view(), basic_params(1.0, 0.5, 0.5));
  for (std::size_t i = 0; i < 3; ++i) EXPECT_EQ(r.status[i], PointStatus::kTooFewNormalPoints) << i;
  EXPECT_EQ(r.status[3], PointStatus::kOk);
  r = compute(ref.view(), cmp.view(), core.view(), vertical_params(0.5, 0.5));
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(r.status[i], PointStatus::kEmptyCylinder1) << i;
    EXPECT_TRUE(std::isnan(r.distance[i])) << i;
  }
  EXPECT_EQ(r.status[3], PointStatus::kOk);
}

TEST(ErrorsEdgeCases, MoreThan65535PointsInOneCylinderAreCountedExactly) {
  // 300 x 300 = 90,000 points on a 1/1024 grid, all within the cylinder of radius 0.5.
  Cloud ref, cmp;
  const double s = 1.0 / 1024;
  for (int i = -150; i < 150; ++i)
    for (int j = -150; j < 150; ++j) {
      ref.add(s * i, s * j, 0.0);
      cmp.add(s * i, s * j, 0.25);
    }
  cmp.add(0.0, 0.0, 0.25);  // one duplicate: n2 = n1 + 1
  const Cloud core = single(0, 0, 0);
  const Result r = compute(ref.view(), cmp.view(), core.view(), basic_params(1.0, 1.0, 0.5));
  ASSERT_EQ(r.status[0], PointStatus::kOk);
  EXPECT_EQ(r.n1[0], 90000u);
  EXPECT_EQ(r.n2[0], 90001u);
  EXPECT_NEAR(r.distance[0], 0.25, 1e-12);
}

}  // namespace
}  // namespace m3c2::test
