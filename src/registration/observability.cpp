#include "registration/observability.hpp"

#include <m3c2/errors.hpp>

#include "support/number_text.hpp"

#include <Eigen/Eigenvalues>

#include <string>

namespace m3c2::detail {
namespace {

std::string vector_text(const Vec3& v) {
  const Vec3 u = v.normalized();
  return "(" + number_text(u.x(), 3) + ", " + number_text(u.y(), 3) + ", " + number_text(u.z(), 3) + ")";
}

}  // namespace

void require_observable(const Matrix6d& jtj, double radius) {
  Vector6d scale;
  scale << 1.0 / radius, 1.0 / radius, 1.0 / radius, 1.0, 1.0, 1.0;
  const Matrix6d scaled = scale.asDiagonal() * jtj * scale.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Matrix6d> eigen(scaled);
  const double largest = eigen.eigenvalues()(5), smallest = eigen.eigenvalues()(0);
  if (largest > 0.0 && smallest >= kUnobservable * largest) return;
  const Vector6d v = eigen.eigenvectors().col(0);
  const Vec3 rotation = v.head<3>(), translation = v.tail<3>();
  const std::string what = translation.norm() >= rotation.norm() ? "translation along " + vector_text(translation)
                                                                 : "rotation about " + vector_text(rotation);
  throw InvalidArgument("the stable points do not constrain the motion: " + what +
                        " is unobservable (J^T J's smallest eigenvalue is " + number_text(smallest / largest, 3) +
                        " of its largest, below " + number_text(kUnobservable, 3) +
                        "): a plane, or a surface that slides along itself; register on areas with relief "
                        "facing several directions");
}

}  // namespace m3c2::detail
