// The closed-form plane fit (src/pipeline/plane_fit.cpp) against Eigen's iterative solver, on thousands
// of seeded random co-moment matrices: planar, noisy, anisotropic, lines, points, zero and
// repeated eigenvalues. Both solvers are backward stable, so they agree to a few ulps of ||A||
// on eigenvalues, and on the normal to eps ||A|| / gap (gap: lambda1 - lambda0).

#include "test_support.hpp"

#include "pipeline/plane_fit.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <random>

namespace m3c2::test {
namespace {

using detail::fit_plane;
using detail::fit_plane_iterative;
using detail::PlaneFit;

/// Co-moment matrix sum (p - mean)(p - mean)^T of a point set, as the engine forms it.
Eigen::Matrix3d comoment_of(const std::vector<Vec3>& pts) {
  Vec3 mean = Vec3::Zero();
  for (const Vec3& p : pts) mean += p;
  mean /= double(pts.size());
  Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
  for (const Vec3& p : pts) c += (p - mean) * (p - mean).transpose();
  return c;
}

/// R diag(l) R^T with a random rotation R (a normalised Gaussian quaternion).
Eigen::Matrix3d rotated(const Vec3& l, std::mt19937_64& rng) {
  std::normal_distribution<double> g;
  const Eigen::Matrix3d r = Eigen::Quaterniond(g(rng), g(rng), g(rng), g(rng)).normalized().toRotationMatrix();
  const Eigen::Matrix3d a = r * l.asDiagonal() * r.transpose();
  return 0.5 * (a + a.transpose());  // exactly symmetric, as the engine's co-moments are
}

double sin_angle(const Vec3& a, const Vec3& b) { return a.normalized().cross(b.normalized()).norm(); }

/// Checks shared by every matrix: the fit is an eigen-decomposition to a few ulps, its
/// eigenvalues and degenerate flag are the iterative solver's, and so is its normal where the
/// normal is well defined (lambda1 - lambda0 >= `gap_share` of lambda2).
void expect_agrees(const Eigen::Matrix3d& a, const std::string& what, double gap_share = 1e-3) {
  SCOPED_TRACE(what);
  const PlaneFit fast = fit_plane(a), ref = fit_plane_iterative(a);
  const double norm = std::max(a.cwiseAbs().maxCoeff(), std::numeric_limits<double>::min());
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(fast.eigenvalues(k), ref.eigenvalues(k), 1e-13 * norm) << k;
  EXPECT_LE(fast.eigenvalues(0), fast.eigenvalues(1));
  EXPECT_LE(fast.eigenvalues(1), fast.eigenvalues(2));
  EXPECT_EQ(fast.degenerate, ref.degenerate);
  ASSERT_TRUE(fast.normal.allFinite());
  EXPECT_NEAR(fast.normal.norm(), 1.0, 1e-15);
  // The normal is an eigenvector of the smallest eigenvalue (residual in ulps of ||A||).
  EXPECT_LE((a * fast.normal - fast.eigenvalues(0) * fast.normal).norm(), 1e-13 * norm);
  EXPECT_TRUE(detail::comoment_eigenvalues(a) == fast.eigenvalues);
  const Vec3 l = ref.eigenvalues;
  if (l(1) - l(0) >= gap_share * l(2)) {
    EXPECT_LE(sin_angle(fast.normal, ref.normal), 1e-12);
  }
}

TEST(PlaneFit, NoisyPlanarNeighbourhoodsMatchIterativeSolver) {
  // Point sets as the normals see them: a disc of radius r on a random plane, with noise from
  // 0 (exactly planar, lambda0 = 0 up to rounding) to r / 3, 4 to 2000 points, offsets up to 1e6.
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::normal_distribution<double> g;
  const double noises[] = {0.0, 1e-9, 1e-6, 1e-4, 1e-2, 0.1, 0.3};
  for (int trial = 0; trial < 3000; ++trial) {
    const double r = std::pow(10.0, 4.0 * u(rng));
    const double noise = noises[trial % 7] * r;
    const std::size_t n = 4 + std::size_t(std::abs(u(rng)) * (trial % 10 == 0 ? 2000 : 60));
    const Vec3 normal = Vec3(g(rng), g(rng), g(rng)).normalized();
    const Vec3 e1 = normal.unitOrthogonal(), e2 = normal.cross(e1);
    const Vec3 centre = 1e6 * Vec3(u(rng), u(rng), u(rng)) * (trial % 3 == 0);
    std::vector<Vec3> pts;
    while (pts.size() < n) {
      const double x = u(rng), y = u(rng);
      if (x * x + y * y <= 1.0) pts.push_back(centre + r * (x * e1 + y * e2) + noise * g(rng) * normal);
    }
    const Eigen::Matrix3d a = comoment_of(pts);
    expect_agrees(a, "trial " + std::to_string(trial));
    if (noise <= 1e-4 * r) {
      EXPECT_LE(sin_angle(fit_plane(a).normal, normal), 1e-3) << trial;
    }
  }
}

TEST(PlaneFit, RandomSpectraMatchIterativeSolver) {
  // Rotated diagonal matrices over 24 orders of magnitude of scale and anisotropy, including
  // exact zeros and pairs or triples of equal eigenvalues.
  std::mt19937_64 rng(12);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int trial = 0; trial < 6000; ++trial) {
    const double scale = std::pow(10.0, 24.0 * u(rng) - 12.0);
    Vec3 l(std::pow(10.0, -16.0 * u(rng)), std::pow(10.0, -8.0 * u(rng)), 1.0);
    switch (trial % 8) {
      case 0: l(0) = 0.0; break;                           // exactly planar
      case 1: l(0) = l(1) = 0.0; break;                    // a line
      case 2: l(1) = l(2); break;                          // an isotropic disc (repeated pair)
      case 3: l(0) = 0.0, l(1) = l(2); break;              // an exact disc on a plane
      case 4: l(0) = l(1); break;                          // a cigar (repeated small pair)
      case 5: l(1) = l(2) * (1.0 - 1e-9 * u(rng)); break;  // a nearly repeated pair
      case 6: l(0) = l(1) = l(2); break;                   // isotropic
      default: break;
    }
    expect_agrees(rotated(scale * l, rng), "trial " + std::to_string(trial));
  }
}

TEST(PlaneFit, AxisAlignedAndExactCases) {
  std::mt19937_64 rng(13);
  expect_agrees(Eigen::Matrix3d::Zero(), "zero");
  expect_agrees(Eigen::Matrix3d::Identity(), "identity");
  expect_agrees(Vec3(0.0, 0.0, 4.0).asDiagonal().toDenseMatrix(), "line along z");
  expect_agrees(Vec3(0.0, 2.0, 2.0).asDiagonal().toDenseMatrix(), "disc, x normal");
  expect_agrees(Vec3(3.0, 1.0, 0.0).asDiagonal().toDenseMatrix(), "plane, z normal");
  expect_agrees(Vec3(1e-300, 1e-300, 2e-300).asDiagonal().toDenseMatrix(), "tiny");
  expect_agrees(Vec3(1e300, 3e299, 1e290).asDiagonal().toDenseMatrix(), "huge");
  // A regular square grid on a plane: lambda1 = lambda2 and lambda0 = 0 exactly in exact
  // arithmetic (the common synthetic test input).
  for (int trial = 0; trial < 200; ++trial) {
    std::normal_distribution<double> g;
    const Vec3 normal = Vec3(g(rng), g(rng), g(rng)).normalized();
    const Vec3 e1 = normal.unitOrthogonal(), e2 = normal.cross(e1);
    std::vector<Vec3> pts;
    for (int i = -5; i <= 5; ++i)
      for (int j = -5; j <= 5; ++j) pts.push_back(0.1 * i * e1 + 0.1 * j * e2);
    const Eigen::Matrix3d a = comoment_of(pts);
    expect_agrees(a, "grid " + std::to_string(trial));
    EXPECT_FALSE(fit_plane(a).degenerate);
    EXPECT_LE(sin_angle(fit_plane(a).normal, normal), 1e-14);
  }
  // Collinear and coincident points: degenerate, as with the iterative solver.
  for (int trial = 0; trial < 200; ++trial) {
    std::normal_distribution<double> g;
    const Vec3 dir = Vec3(g(rng), g(rng), g(rng)).normalized(), base(g(rng), g(rng), g(rng));
    std::vector<Vec3> line, point(5, base);
    for (int i = 0; i < 20; ++i) line.push_back(base + g(rng) * dir);
    expect_agrees(comoment_of(line), "line " + std::to_string(trial));
    expect_agrees(comoment_of(point), "point " + std::to_string(trial));
    EXPECT_TRUE(fit_plane(comoment_of(line)).degenerate);
    EXPECT_TRUE(fit_plane(comoment_of(point)).degenerate);
  }
}

TEST(PlaneFit, NonFiniteIsDegenerate) {
  Eigen::Matrix3d a = Eigen::Matrix3d::Identity();
  a(0, 1) = a(1, 0) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(fit_plane(a).degenerate);
  a(0, 1) = a(1, 0) = std::numeric_limits<double>::infinity();
  EXPECT_TRUE(fit_plane(a).degenerate);
}

}  // namespace
}  // namespace m3c2::test
