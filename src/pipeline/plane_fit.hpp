#pragma once
// The plane of a neighbourhood from its co-moment matrix (section 3.1.2: the normal is the
// eigenvector of the smallest eigenvalue).

#include <m3c2/points_view.hpp>

#include <Eigen/Core>

namespace m3c2::detail {

struct PlaneFit {
  Vec3 normal;                  ///< unit, not oriented
  Eigen::Vector3d eigenvalues;  ///< ascending, of the co-moment matrix
  bool degenerate = true;       ///< a line, a point or non-finite: no plane
};

/// Eigen-decomposition of the symmetric co-moment matrix sum (v - mean)(v - mean)^T: closed
/// form (~0.21 us against ~0.43 us, bench/plane_fit_bench.cpp), falling back to the iterative
/// solver where its residual is not a few ulps.
PlaneFit fit_plane(const Eigen::Matrix3d& comoment);

/// Ascending eigenvalues only (roughness at several scales), as fit_plane computes them.
Eigen::Vector3d comoment_eigenvalues(const Eigen::Matrix3d& comoment);

/// fit_plane with Eigen's iterative SelfAdjointEigenSolver only: the reference the
/// closed form is tested against (tests/cpp/test_plane_fit.cpp, bench/plane_fit_bench.cpp).
PlaneFit fit_plane_iterative(const Eigen::Matrix3d& comoment);

}  // namespace m3c2::detail
