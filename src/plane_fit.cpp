#include "plane_fit.hpp"

#include <Eigen/Eigenvalues>

namespace m3c2::detail {
namespace {

// Neighbourhoods whose middle eigenvalue is below this share of the largest are lines or single
// points: the plane, hence the normal, is undefined there.
constexpr double kCollinearRatio = 1e-12;

}  // namespace

PlaneFit fit_plane(const Eigen::Matrix3d& comoment) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(comoment);
  PlaneFit fit;
  fit.eigenvalues = solver.eigenvalues();
  fit.normal = solver.eigenvectors().col(0).normalized();
  const double largest = fit.eigenvalues(2);
  fit.degenerate = !(largest > 0.0) || !(fit.eigenvalues(1) > kCollinearRatio * largest) || !fit.normal.allFinite();
  return fit;
}

Eigen::Vector3d comoment_eigenvalues(const Eigen::Matrix3d& comoment) {
  return Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(comoment, Eigen::EigenvaluesOnly).eigenvalues();
}

}  // namespace m3c2::detail
