// Brute-force oracles for the two neighbourhood queries (sections 3.1.2 and 3.1.3):
// the projection cylinder (squared distance to the axis <= (d/2)^2, |t| <= max_depth, both
// inclusive) and the normal ball (distance <= D/2, inclusive).

#include "test_support.hpp"

namespace m3c2::test {
namespace {

// Cloud with every coordinate a multiple of 0.125 in [0, 4] (so all differences, squares and
// sums of squares below are exact in binary floating point).
Cloud quantised_cloud(std::uint64_t seed, std::size_t n) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> k(0, 32);
  Cloud c;
  for (std::size_t i = 0; i < n; ++i) {
    const int a = k(rng), b = k(rng), d = k(rng);
    c.add(0.125 * a, 0.125 * b, 0.125 * d);
  }
  return c;
}

Cloud quantised_cores(std::uint64_t seed, std::size_t n) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> k(4, 28);  // [0.5, 3.5]: away from the cloud's edges
  Cloud c;
  for (std::size_t i = 0; i < n; ++i) {
    const int a = k(rng), b = k(rng), d = k(rng);
    c.add(0.125 * a, 0.125 * b, 0.125 * d);
  }
  return c;
}

TEST(CylinderQuery, CountsMatchBruteForceOnRandomClouds) {
  // Random 3D clouds: PCA normals point anywhere, so the cylinder is arbitrarily oriented.
  // The oracle uses the engine's own normal. A random point lies within 1e-12 of the cylinder
  // wall with probability ~1e-11, so exact agreement is expected.
  const Cloud ref = random_box(101, 4000, Vec3(0, 0, 0), Vec3(4, 4, 2));
  const Cloud cmp = random_box(202, 4000, Vec3(0, 0, 0), Vec3(4, 4, 2));
  const Cloud cores = random_box(303, 200, Vec3(0.5, 0.5, 0.5), Vec3(3.5, 3.5, 1.5));
  const Params p = basic_params(/*D=*/1.2, /*d=*/0.9, /*max_depth=*/0.7);
  const Result r = compute(ref.view(), cmp.view(), cores.view(), p);
  std::size_t checked = 0;
  for (std::size_t i = 0; i < cores.size(); ++i) {
    if (r.status[i] == PointStatus::kTooFewNormalPoints || r.status[i] == PointStatus::kDegenerateNormal) continue;
    const Vec3 n = normal_at(r.normal, i);
    EXPECT_EQ(r.n1[i], brute_cylinder_count(ref, cores[i], n, 0.45, -0.7, 0.7)) << "core " << i;
    EXPECT_EQ(r.n2[i], brute_cylinder_count(cmp, cores[i], n, 0.45, -0.7, 0.7)) << "core " << i;
    ++checked;
  }
  EXPECT_GT(checked, 190u);
}

TEST(CylinderQuery, CountsMatchBruteForceOnSurfaceClouds) {
  const Pair pr = rough_pair(404, 5000, 8.0, 0.02, 0.3);
  Params p = basic_params(1.0, 0.6, 1.5);
  const Result r = compute(pr.reference.view(), pr.compared.view(), pr.cores.view(), p);
  std::size_t checked = 0;
  for (std::size_t i = 0; i < pr.cores.size(); ++i) {
    if (!std::isfinite(r.normal[3 * i])) continue;
    const Vec3 n = normal_at(r.normal, i);
    EXPECT_EQ(r.n1[i], brute_cylinder_count(pr.reference, pr.cores[i], n, 0.3, -1.5, 1.5)) << i;
    EXPECT_EQ(r.n2[i], brute_cylinder_count(pr.compared, pr.cores[i], n, 0.3, -1.5, 1.5)) << i;
    ++checked;
  }
  EXPECT_GT(checked, pr.cores.size() * 9 / 10);
}

// Quantised clouds with core points on the grid, vertical normals, d = 0.5 (r^2 = 0.0625) and
// max_depth = 0.5: many points lie exactly on the cylinder wall and exactly at |t| = max_depth,
// and every quantity is exact, so the counts must match the inclusive brute force exactly.
TEST(CylinderQuery, InclusiveBoundariesOnQuantisedCloudWithVerticalNormals) {
  const Cloud ref = quantised_cloud(11, 6000);
  const Cloud cmp = quantised_cloud(22, 6000);
  const Cloud cores = quantised_cores(33, 300);
  Params p = basic_params(0.5, 0.5, 0.5);
  p.normal_source = NormalSource::kVertical;
  const Result r = compute(ref.view(), cmp.view(), cores.view(), p);

  std::size_t on_wall = 0, on_cap = 0;
  for (std::size_t i = 0; i < cores.size(); ++i) {
    EXPECT_EQ(r.n1[i], brute_cylinder_count(ref, cores[i], Vec3::UnitZ(), 0.25, -0.5, 0.5)) << "core " << i;
    EXPECT_EQ(r.n2[i], brute_cylinder_count(cmp, cores[i], Vec3::UnitZ(), 0.25, -0.5, 0.5)) << "core " << i;
    for (std::size_t k = 0; k < ref.size(); ++k) {
      const Vec3 d = ref[k] - cores[i];
      const double r2 = d.x() * d.x() + d.y() * d.y();
      if (r2 == 0.0625 && std::abs(d.z()) <= 0.5) ++on_wall;
      if (r2 <= 0.0625 && std::abs(d.z()) == 0.5) ++on_cap;
    }
  }
  // The test exercises the boundaries many times (non-vacuity).
  EXPECT_GT(on_wall, 100u);
  EXPECT_GT(on_cap, 100u);
}

TEST(CylinderQuery, PositiveSearchOnlyCountsTInZeroToMaxDepth) {
  const Cloud ref = quantised_cloud(44, 6000);
  const Cloud cmp = quantised_cloud(55, 6000);
  const Cloud cores = quantised_cores(66, 200);
  Params p = basic_params(0.5, 0.5, 0.5);
  p.normal_source = NormalSource::kVertical;
  p.positive_search_only = true;
  const Result r = compute(ref.view(), cmp.view(), cores.view(), p);
  for (std::size_t i = 0; i < cores.size(); ++i) {
    EXPECT_EQ(r.n1[i], brute_cylinder_count(ref, cores[i], Vec3::UnitZ(), 0.25, 0.0, 0.5)) << "core " << i;
    EXPECT_EQ(r.n2[i], brute_cylinder_count(cmp, cores[i], Vec3::UnitZ(), 0.25, 0.0, 0.5)) << "core " << i;
  }
}

TEST(NormalQuery, NeighbourCountMatchesInclusiveBallOnQuantisedCloud) {
  // D = 0.5: squared distances are multiples of 1/64, many exactly 0.0625 = (D/2)^2.
  const Cloud cloud = quantised_cloud(77, 20000);
  const Cloud cores = quantised_cores(88, 300);
  Params p;
  p.normal_diameters = {0.5};
  const NormalsResult nr = compute_normals(cloud.view(), cores.view(), p);
  ASSERT_EQ(nr.size(), cores.size());
  std::size_t checked = 0, on_sphere = 0;
  for (std::size_t i = 0; i < cores.size(); ++i) {
    for (std::size_t k = 0; k < cloud.size(); ++k) on_sphere += (cloud[k] - cores[i]).squaredNorm() == 0.0625;
    if (nr.status[i] != PointStatus::kOk) continue;
    EXPECT_EQ(nr.count[i], brute_ball_count(cloud, cores[i], 0.25)) << "core " << i;
    ++checked;
  }
  EXPECT_GT(checked, 270u);
  EXPECT_GT(on_sphere, 100u);
}

TEST(NormalQuery, NeighbourCountMatchesBallOnRandomCloud) {
  const Cloud cloud = random_box(99, 8000, Vec3(0, 0, 0), Vec3(5, 5, 1));
  const Cloud cores = random_box(98, 300, Vec3(0.5, 0.5, 0.2), Vec3(4.5, 4.5, 0.8));
  Params p;
  p.normal_diameters = {0.8};
  const NormalsResult nr = compute_normals(cloud.view(), cores.view(), p);
  for (std::size_t i = 0; i < cores.size(); ++i) {
    ASSERT_EQ(nr.status[i], PointStatus::kOk) << i;
    EXPECT_EQ(nr.count[i], brute_ball_count(cloud, cores[i], 0.4)) << "core " << i;
    EXPECT_EQ(nr.normal_scale[i], 0.8);
  }
}

}  // namespace
}  // namespace m3c2::test
