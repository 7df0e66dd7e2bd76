#pragma once
// Rigid registration of the compared cloud onto the reference: point-to-plane ICP (Chen & Medioni
// 1992; the iteration of Besl & McKay 1992) on the points of stable areas, with the covariance of
// its six parameters. Its residual is the `reg` of eq. (1) (Lague et al. 2013, section 3.3);
// docs/registration.md derives each step.

#include <m3c2/points_view.hpp>
#include <m3c2/run_options.hpp>

#include <array>
#include <cstdint>

namespace m3c2 {

/// What register_clouds() does. Lengths are in the clouds' unit.
struct RegistrationParams {
  /// D: the DIAMETER of the reference neighbourhood whose plane gives each target's normal (3.1.2).
  double normal_diameter = 0.0;
  /// Pairs whose points are farther apart than this are not the same surface (ICP's max
  /// correspondence distance); it also bounds the nearest-neighbour search.
  double max_distance = 0.0;
  /// Residual rejection: a pair whose residual is more than `reject` robust standard deviations
  /// (1.4826 MAD) from the residuals' median is dropped; 0 keeps every pair within max_distance.
  double reject = 3.0;
  /// The most Gauss-Newton steps (each one re-pairs the points).
  std::uint32_t max_iterations = 50;
  /// Converged when a step moves no compared point by more than `tolerance` times the compared
  /// points' RMS distance to their centre (relative: any unit). Re-pairing is discrete, so the
  /// steps end in a cycle rather than at 0; 1e-6 of a 10 m site is 10 micrometres.
  double tolerance = 1e-6;
  /// Fewest pairs a step may be solved from (six parameters, and a residual variance to estimate).
  std::uint32_t min_pairs = 50;
  /// At most this many compared points are paired, taken at a fixed stride (deterministic): the
  /// parameters' standard errors fall as 1 / sqrt(pairs), the run's cost grows with them.
  std::uint64_t max_points = 1'000'000;
};

/// The estimate. The motion is p' = R (p - centre) + centre + t; `matrix` is the same motion about
/// the origin, row-major 4x4: p' = M[:3, :3] p + M[:3, 3].
struct Registration {
  std::array<double, 16> matrix{};
  /// Covariance (row-major 6x6) of (rx, ry, rz, tx, ty, tz) = (w, s) in p' = exp([w]x) (M p - c) + c + s:
  /// a small rotation vector (radians) about `centre` c after the estimate M, then a shift.
  /// sigma^2 (J^T J)^-1, sigma^2 = sum r^2 / (pairs - 6): valid when the residuals are independent.
  std::array<double, 36> covariance{};
  std::array<double, 3> centre{};   ///< the mean of the paired compared points (conditioning)
  double registration_error = 0.0;  ///< sqrt(sum r^2 / (pairs - 6)) over the final pairs
  double rms = 0.0;                 ///< sqrt(mean r^2) over the final pairs
  std::uint64_t pairs = 0;          ///< pairs of the final estimate (after rejection)
  std::uint64_t candidates = 0;     ///< compared points sampled (max_points)
  std::uint32_t iterations = 0;
  bool converged = false;
};

/// Point-to-plane ICP of `compared` onto `reference` (both the stable areas' points). Throws
/// InvalidArgument for an empty cloud, a non-finite coordinate, bad parameters, fewer than
/// min_pairs pairs, or geometry that leaves a motion unobservable (a plane: translation along it);
/// Cancelled when run.progress says so. The same bits for any thread count.
Registration register_clouds(PointsView reference, PointsView compared, const RegistrationParams& params,
                             const RunOptions& run = {});

}  // namespace m3c2
