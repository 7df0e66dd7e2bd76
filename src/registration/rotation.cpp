#include "registration/rotation.hpp"

#include <cmath>

namespace m3c2::detail {

Eigen::Matrix3d cross_matrix(const Vec3& w) {
  Eigen::Matrix3d k;
  k << 0.0, -w.z(), w.y(), w.z(), 0.0, -w.x(), -w.y(), w.x(), 0.0;
  return k;
}

Eigen::Matrix3d rotation_from_vector(const Vec3& w) {
  const double angle = w.norm();
  const Eigen::Matrix3d k = cross_matrix(w);
  // Below 1e-8 rad the series 1 - a^2/6 and 1/2 - a^2/24 are exact in float64 and avoid 0/0.
  const double a = angle < 1e-8 ? 1.0 - angle * angle / 6.0 : std::sin(angle) / angle;
  const double b = angle < 1e-8 ? 0.5 - angle * angle / 24.0 : (1.0 - std::cos(angle)) / (angle * angle);
  return Eigen::Matrix3d::Identity() + a * k + b * k * k;
}

}  // namespace m3c2::detail
