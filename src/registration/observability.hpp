#pragma once
// Whether the stable points constrain all six parameters of the motion: a plane leaves the two
// translations along it and the rotation about its normal free (J^T J singular), and ICP would
// return whatever its rounding gave them.

#include "registration/pairing.hpp"

namespace m3c2::detail {

/// Below this ratio of J^T J's smallest to largest eigenvalue (rotations scaled by the sources'
/// radius, so that both are lengths) a direction of the motion counts as unobservable: its
/// standard error would be more than 100 times the best-constrained one's. Noisy planes sit at
/// 1e-6..1e-4 (normals tilted only by noise), rough terrain at 1e-2 and above.
inline constexpr double kUnobservable = 1e-4;

/// Throws InvalidArgument naming the least-constrained direction (a translation along a vector or
/// a rotation about an axis) when `jtj` is too close to singular; `radius` scales the rotations.
void require_observable(const Matrix6d& jtj, double radius);

}  // namespace m3c2::detail
