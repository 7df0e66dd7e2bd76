// Point-to-plane ICP (include/m3c2/registration.hpp): known motions recovered on rough terrain,
// a plane refused, the covariance's calibration, the same bits for any thread count, bad inputs.

#include <m3c2/registration.hpp>

#include "registration/rotation.hpp"
#include "test_support.hpp"

#include <cstring>

namespace m3c2::test {
namespace {

constexpr double kDegree = 3.14159265358979323846 / 180.0;

/// The motion compared -> reference: p_ref = R p_cmp + t.
struct Motion {
  Eigen::Matrix3d rotation;
  Vec3 translation;
};

Motion motion(const Vec3& rotation_vector, const Vec3& translation) {
  return {detail::rotation_from_vector(rotation_vector), translation};
}

/// The compared epoch: the surface sampled at random (xy on [0, extent]^2), noisy along z, then
/// moved by the inverse of `m` so that `m` maps it back onto the reference.
Cloud compared_epoch(std::uint64_t seed, std::size_t n, double extent, double noise, const Motion& m) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, extent);
  std::normal_distribution<double> g(0.0, noise);
  Cloud c;
  for (std::size_t i = 0; i < n; ++i) {
    const double x = u(rng), y = u(rng);
    const Vec3 p(x, y, rough_height(x, y) + g(rng));
    c.add(m.rotation.transpose() * (p - m.translation));
  }
  return c;
}

Cloud reference_grid(double extent, double spacing) {
  const int n = int(extent / spacing) + 1;
  return height_grid(0.0, 0.0, n, n, spacing, rough_height);
}

RegistrationParams params() {
  RegistrationParams p;
  p.normal_diameter = 0.5;
  p.max_distance = 0.5;
  return p;
}

double rotation_error_degrees(const Registration& r, const Motion& m) {
  Eigen::Matrix3d got;
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) got(a, b) = r.matrix[4 * a + b];
  const Eigen::AngleAxisd diff(got * m.rotation.transpose());
  return std::abs(diff.angle()) / kDegree;
}

double translation_error(const Registration& r, const Motion& m) {
  return (Vec3(r.matrix[3], r.matrix[7], r.matrix[11]) - m.translation).norm();
}

TEST(Registration, RecoversAKnownMotionOnRoughTerrain) {
  const Motion m = motion(Vec3(0.2, -0.1, 0.3) * kDegree, Vec3(0.05, -0.03, 0.02));
  const Cloud reference = reference_grid(12.0, 0.05);
  const Cloud compared = compared_epoch(11, 40000, 12.0, 0.002, m);
  const Registration r = register_clouds(reference.view(), compared.view(), params());
  EXPECT_TRUE(r.converged);
  EXPECT_LE(rotation_error_degrees(r, m), 0.001) << "sd about z " << std::sqrt(r.covariance[14]) / kDegree;
  EXPECT_LE(translation_error(r, m), 0.001);
  EXPECT_NEAR(r.registration_error, 0.002, 0.0005);  // the noise: nothing else is left
  EXPECT_EQ(r.matrix[15], 1.0);
}

TEST(Registration, SameBitsForAnyThreadCount) {
  const Motion m = motion(Vec3(0.1, 0.1, -0.2) * kDegree, Vec3(0.02, 0.01, -0.03));
  const Cloud reference = compared_epoch(3, 20000, 10.0, 0.01, motion(Vec3::Zero(), Vec3::Zero()));
  const Cloud compared = compared_epoch(4, 20000, 10.0, 0.01, m);
  const Registration one = register_clouds(reference.view(), compared.view(), params(), with_threads(1));
  for (const int threads : {2, 3}) {
    const Registration many = register_clouds(reference.view(), compared.view(), params(), with_threads(threads));
    EXPECT_EQ(std::memcmp(one.matrix.data(), many.matrix.data(), sizeof one.matrix), 0) << threads;
    EXPECT_EQ(std::memcmp(one.covariance.data(), many.covariance.data(), sizeof one.covariance), 0) << threads;
    EXPECT_EQ(one.registration_error, many.registration_error);
    EXPECT_EQ(one.pairs, many.pairs);
  }
}

TEST(Registration, APlaneIsRefusedNamingTheFreeMotion) {
  std::mt19937_64 rng(5);
  std::normal_distribution<double> g(0.0, 0.002);
  Cloud reference, compared;
  for (int i = 0; i < 100; ++i)
    for (int j = 0; j < 100; ++j) {
      reference.add(0.1 * i, 0.1 * j, g(rng));
      compared.add(0.1 * i + 0.05, 0.1 * j + 0.03, 0.01 + g(rng));
    }
  try {
    register_clouds(reference.view(), compared.view(), params());
    FAIL() << "a plane was registered";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("unobservable"), std::string::npos) << e.what();
  }
}

TEST(Registration, CovarianceCoversTheTrueParametersAt95Percent) {
  // Independent noise on the compared points only (a dense exact reference): the residuals are
  // independent, the assumption of sigma^2 (J^T J)^-1. Each parameter's error, in the covariance's
  // frame (a rotation about the centre after the estimate, the centre's shift), within 1.96 sd
  // in 95 % of the draws: 200 draws x 6 parameters, binomial sd 0.63 %, tolerance 3 sd.
  const Cloud reference = reference_grid(5.0, 0.05);
  RegistrationParams p = params();
  p.normal_diameter = 0.4;
  const int draws = 200;
  int covered = 0, total = 0;
  for (int k = 0; k < draws; ++k) {
    const Motion m = motion(Vec3(0.1, -0.2, 0.15) * kDegree, Vec3(0.01, 0.02, -0.01));
    const Cloud compared = compared_epoch(1000 + k, 1500, 5.0, 0.02, m);
    const Registration r = register_clouds(reference.view(), compared.view(), p, with_threads(1));
    Eigen::Matrix3d got;
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) got(a, b) = r.matrix[4 * a + b];
    const Vec3 centre(r.centre[0], r.centre[1], r.centre[2]);
    // truth p = exp([w]x) (got p - centre) + centre + s: w from the residual rotation, s the shift
    // of the point the estimate puts at the centre.
    const Eigen::AngleAxisd residual(m.rotation * got.transpose());
    const Vec3 w = residual.angle() * residual.axis();
    const Vec3 at_centre = got.transpose() * (centre - Vec3(r.matrix[3], r.matrix[7], r.matrix[11]));
    const Vec3 shift = m.rotation * at_centre + m.translation - centre;
    for (int a = 0; a < 6; ++a) {
      const double error = a < 3 ? w(a) : shift(a - 3);
      covered += std::abs(error) <= 1.96 * std::sqrt(r.covariance[7 * a]);
      ++total;
    }
  }
  const double rate = double(covered) / total;
  EXPECT_NEAR(rate, 0.95, 3 * std::sqrt(0.95 * 0.05 / total)) << covered << " of " << total;
}

TEST(Registration, TooFewPairsWhenTheCloudsAreFarApart) {
  const Cloud reference = reference_grid(5.0, 0.1);
  const Cloud compared = reference.translated(Vec3(0.0, 0.0, 10.0));
  EXPECT_THROW(register_clouds(reference.view(), compared.view(), params()), InvalidArgument);
}

TEST(Registration, BadInputsAreRefused) {
  const Cloud reference = reference_grid(5.0, 0.1);
  Cloud bad = reference;
  bad.xyz[7] = kNaN;
  EXPECT_THROW(register_clouds(reference.view(), bad.view(), params()), InvalidArgument);
  EXPECT_THROW(register_clouds(Cloud{}.view(), reference.view(), params()), InvalidArgument);
  RegistrationParams p = params();
  p.max_distance = 0.0;
  EXPECT_THROW(register_clouds(reference.view(), reference.view(), p), InvalidArgument);
}

}  // namespace
}  // namespace m3c2::test
