#include "pipeline/plane_fit.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>

namespace m3c2::detail {
namespace {

// Neighbourhoods whose middle eigenvalue is below this share of the largest are lines or single
// points: the plane, hence the normal, is undefined there.
constexpr double kCollinearRatio = 1e-12;

// The closed form is accepted when every residual ||A v - lambda v|| is below this share of
// ||A||_max. A backward-stable solver (the iterative one included) leaves a few ulps (~1e-15);
// anything above means the closed form went wrong and the iterative solver decides.
constexpr double kResidualTolerance = 1e-12;

struct Eigen3 {
  Eigen::Vector3d values;   // ascending
  Eigen::Matrix3d vectors;  // unit columns, in the order of `values` (the closed form sets col 0 only)
};

/// The iterative solver (tridiagonalisation + implicit QL, ~0.43 us here): the reference,
/// and the fallback of the closed form.
Eigen3 iterative(const Eigen::Matrix3d& a) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(a);
  return {solver.eigenvalues(), solver.eigenvectors()};
}

/// Unit vector spanning the kernel of the rank-2 symmetric `m`: the largest of the cross
/// products of its rows (the pair closest to orthogonal is the best conditioned).
Eigen::Vector3d kernel_of_rank2(const Eigen::Matrix3d& m) {
  const Eigen::Vector3d r0 = m.row(0), r1 = m.row(1), r2 = m.row(2);
  const std::array<Eigen::Vector3d, 3> c = {r0.cross(r1), r0.cross(r2), r1.cross(r2)};
  const std::array<double, 3> n = {c[0].squaredNorm(), c[1].squaredNorm(), c[2].squaredNorm()};
  const int best = n[0] >= n[1] ? (n[0] >= n[2] ? 0 : 2) : (n[1] >= n[2] ? 1 : 2);
  return c[best] / std::sqrt(n[best]);
}

/// b restricted to the plane orthogonal to the unit v: a 2x2 symmetric, diagonalised by one
/// Jacobi rotation (Numerical Recipes 11.1: t = tan of the angle, the smaller root of
/// t^2 + 2 tau t - 1 = 0, computed without cancellation). Its eigenvalues, ascending, are exact
/// to rounding whatever their gap; `vectors`, if given, receives the matching unit vectors.
Eigen::Vector2d plane_pair(const Eigen::Matrix3d& b, const Eigen::Vector3d& v, Eigen::Vector3d* vectors = nullptr) {
  const Eigen::Vector3d w1 = v.unitOrthogonal(), w2 = v.cross(w1);
  const Eigen::Vector3d bw1 = b * w1, bw2 = b * w2;
  const double c11 = w1.dot(bw1), c22 = w2.dot(bw2), c12 = 0.5 * (w1.dot(bw2) + w2.dot(bw1));
  const double tau = (c22 - c11) / (2.0 * c12);
  // c12 = 0 or negligible against c22 - c11 (tau infinite): already diagonal.
  const double t = std::isfinite(tau) ? (tau >= 0.0 ? 1.0 : -1.0) / (std::abs(tau) + std::sqrt(1.0 + tau * tau)) : 0.0;
  const double e1 = c11 - t * c12, e2 = c22 + t * c12;  // for c w1 - s w2 and s w1 + c w2
  const bool swap = e2 < e1;
  if (vectors) {
    const double c = 1.0 / std::sqrt(1.0 + t * t), s = t * c;
    vectors[swap ? 1 : 0] = c * w1 - s * w2;
    vectors[swap ? 0 : 1] = s * w1 + c * w2;
  }
  return swap ? Eigen::Vector2d(e2, e1) : Eigen::Vector2d(e1, e2);
}

/// Closed-form eigen-decomposition of the symmetric 3x3 `a` (~0.21 us here) as accurate as the
/// iterative solver; only the normal (eigenvector of the smallest eigenvalue) is computed.
/// The trigonometric roots of the characteristic cubic (Smith 1961, as in Eigen's
/// computeDirect) carry an error ~ eps / gap (spread units) on a root at `gap` from another,
/// and the kernel of A - lambda I, the eigenvector, ~ eps / gap^2: so a root and its kernel are
/// used only at a gap >= kPairGap, the other eigenpairs come from one exact Jacobi rotation of
/// A restricted to the plane orthogonal to the most distinct root's eigenvector (Eigen's
/// computeDirect lacks this: near-planar discs with lambda1 ~ lambda2 are common).
/// Returns false where the result cannot be trusted (non-finite, residual above a few ulps).
bool closed_form(const Eigen::Matrix3d& a, Eigen::Vector3d& values, Eigen::Vector3d& normal) {
  // Shift by the mean eigenvalue and scale to [-1, 1]: the cubic is then well scaled, and the
  // spread of the eigenvalues of `b` is >= 1 (b is traceless with max |b_ij| = 1).
  constexpr double kPairGap = 0.1;  // normal error <= eps / kPairGap^2 ~ 2e-14 rad
  const double shift = a.trace() / 3.0;
  Eigen::Matrix3d b = a;
  b.diagonal().array() -= shift;
  const double scale = b.cwiseAbs().maxCoeff();
  if (!(scale > 0.0) || !std::isfinite(scale)) return false;  // a multiple of I, or non-finite
  b *= 1.0 / scale;

  // det(b - x I) = 0 as x^3 - 3 p x - 2 q = 0 (trace 0): x = 2 sqrt(p) cos(theta + 2 pi k / 3),
  // theta in [0, pi / 3]: k = 0 gives the largest root, k = 1 the smallest.
  const double p = (b(0, 0) * b(0, 0) + b(1, 1) * b(1, 1) + b(2, 2) * b(2, 2)) / 6.0 +
                   (b(0, 1) * b(0, 1) + b(0, 2) * b(0, 2) + b(1, 2) * b(1, 2)) / 3.0;
  const double q = b.determinant() / 2.0;
  const double sqrt_p = std::sqrt(p);
  const double theta = std::acos(std::clamp(q / (p * sqrt_p), -1.0, 1.0)) / 3.0;
  Eigen::Vector3d x;
  x(2) = 2.0 * sqrt_p * std::cos(theta);
  x(0) = 2.0 * sqrt_p * std::cos(theta + 2.0 * std::numbers::pi / 3.0);
  x(1) = -x(0) - x(2);  // the roots sum to the trace, 0

  const auto kernel_at = [&](double root) {
    Eigen::Matrix3d m = b;
    m.diagonal().array() -= root;
    return kernel_of_rank2(m);
  };
  if (x(1) - x(0) >= kPairGap || x(1) - x(0) >= x(2) - x(1)) {
    normal = kernel_at(x(0));  // the usual case: the smallest root is well separated
    if (x(2) - x(1) < kPairGap) x.tail<2>() = plane_pair(b, normal);  // a disc: lambda1 ~ lambda2
  } else {
    // A cigar (lambda0 ~ lambda1): the normal from the rotation orthogonal to the long axis.
    Eigen::Vector3d pair[2];
    x.head<2>() = plane_pair(b, kernel_at(x(2)), pair);
    normal = pair[0];
  }
  values = x * scale + Eigen::Vector3d::Constant(shift);
  // The smallest eigenvalue as the Rayleigh quotient of `a` itself: no shift to undo, so it
  // keeps the absolute accuracy of the entries (eps ||A||), as the iterative solver does.
  const Eigen::Vector3d an = a * normal;
  values(0) = std::min(normal.dot(an), values(1));
  const double residual = (an - values(0) * normal).norm();
  return values.allFinite() && normal.allFinite() && residual <= kResidualTolerance * a.cwiseAbs().maxCoeff();
}

/// Ascending eigenvalues and the unit normal (eigenvector of the smallest): closed form,
/// else the iterative solver.
Eigen3 decompose(const Eigen::Matrix3d& a) {
  Eigen3 e;
  Eigen::Vector3d normal;
  if (closed_form(a, e.values, normal)) {
    e.vectors.col(0) = normal;
    return e;
  }
  return iterative(a);
}

}  // namespace

PlaneFit fit_plane(const Eigen::Matrix3d& comoment) {
  const Eigen3 e = decompose(comoment);
  PlaneFit fit;
  fit.eigenvalues = e.values;
  fit.normal = e.vectors.col(0).normalized();
  const double largest = fit.eigenvalues(2);
  fit.degenerate = !(largest > 0.0) || !(fit.eigenvalues(1) > kCollinearRatio * largest) || !fit.normal.allFinite();
  return fit;
}

Eigen::Vector3d comoment_eigenvalues(const Eigen::Matrix3d& comoment) { return decompose(comoment).values; }

PlaneFit fit_plane_iterative(const Eigen::Matrix3d& comoment) {
  const Eigen3 e = iterative(comoment);
  PlaneFit fit;
  fit.eigenvalues = e.values;
  fit.normal = e.vectors.col(0).normalized();
  const double largest = fit.eigenvalues(2);
  fit.degenerate = !(largest > 0.0) || !(fit.eigenvalues(1) > kCollinearRatio * largest) || !fit.normal.allFinite();
  return fit;
}

}  // namespace m3c2::detail
