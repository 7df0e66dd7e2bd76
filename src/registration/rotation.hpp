#pragma once
// Rotations of the registration's Gauss-Newton steps: a rotation vector to its matrix (Rodrigues'
// formula), so that every step leaves the estimate an exact rotation (no re-orthonormalisation).

#include <m3c2/points_view.hpp>

#include <Eigen/Core>

namespace m3c2::detail {

/// The rotation by |w| radians about w / |w| (the identity for w = 0).
Eigen::Matrix3d rotation_from_vector(const Vec3& w);

/// The cross-product matrix [w]x: [w]x v = w x v.
Eigen::Matrix3d cross_matrix(const Vec3& w);

}  // namespace m3c2::detail
