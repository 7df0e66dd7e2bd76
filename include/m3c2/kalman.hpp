#pragma once
// A linear Kalman filter and Rauch-Tung-Striebel (RTS) smoother over each core point's M3C2
// distance series (docs/series.md, "Kalman filter"), after Winiwarter et al. (2023, "Full
// four-dimensional change analysis of topographic point cloud time series using Kalman
// filtering", Earth Surf. Dynam. 11: 593-613). The state of a core point is x = [d, d'] (the
// velocity model) or [d, d', d''] (the acceleration model); the epochs' times may be irregular;
// each epoch observes d with the variance of its own level of detection. Rows of row-major
// [core point][epoch] arrays; NaN marks an epoch without an observation (predicted only).
// Every row is independent: the same bits for any thread count and any split into blocks.

#include <m3c2/params.hpp>
#include <m3c2/run_options.hpp>

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace m3c2 {

/// The state's order: the velocity model tracks d and d', the acceleration model d, d', d''.
enum class KalmanModel : std::uint8_t { kVelocity = 2, kAcceleration = 3 };

/// How the white noise drives the state between two epochs dt apart: Q = q * M(dt).
/// kContinuous: continuous white noise on the highest derivative, q its spectral density
/// (velocity: M = [[dt^3/3, dt^2/2], [dt^2/2, dt]]); two steps of dt equal one of 2 dt, so the
/// model does not depend on where epochs (or skipped ones) fall. kDiscrete: the piecewise-constant
/// white noise of filterpy's Q_discrete_white_noise (M = g g^T, g = [dt^2/2, dt] or
/// [dt^2/2, dt, 1]) that kalman4d and the tum-rsa py4dgeo fork use, q their sigma^2.
enum class KalmanNoise : std::uint8_t { kContinuous, kDiscrete };

/// Numbers per epoch of the filtered moments: the mean (k) and the covariance's upper triangle
/// (row by row: P00, P01, [P02,] P11, [P12, P22]).
constexpr std::size_t kalman_moments(KalmanModel m) {
  const std::size_t k = std::size_t(m);
  return k + k * (k + 1) / 2;
}

struct KalmanParams {
  KalmanModel model = KalmanModel::kVelocity;
  KalmanNoise noise = KalmanNoise::kContinuous;
  double process_noise = 0.0;  ///< q >= 0 (see KalmanNoise), in the distances' unit and the times' unit
  /// Where a row's filter starts. false (the default): at its first observed epoch, with
  /// d = that observation, var(d) = its variance, the derivatives 0 with the variances of
  /// `initial_variance` [1] and [2]. true: at time `prior_time` (before every epoch) with mean
  /// `prior_mean` (per row, or 0 when none is given) and covariance diag(initial_variance),
  /// predicted to the first epoch (how kalman4d anchors d = 0 at the reference epoch).
  bool prior_given = false;
  double prior_time = 0.0;
  /// Variances of d, d', d'' at the start ((unit / day)^2 for the rate): 1 for the derivatives,
  /// both references' P0 = I, large for geomorphic rates in metres (docs/series.md).
  std::array<double, 3> initial_variance{0.0, 1.0, 1.0};
};

/// One block of core points. `values`, `variance`: rows x epochs (observation and its variance;
/// NaN in either: no observation). `times`: the epochs' times, non-decreasing, finite.
/// `moments`: rows x epochs x kalman_moments(model), the filtered state at each epoch (NaN
/// before a row's start): the epochs before `resume_from` are read (kept from an earlier run on
/// the same epochs, parameters and observations), the others written. `prior_mean`: rows x k or null.
struct KalmanBlock {
  const double* values = nullptr;
  const double* variance = nullptr;
  const double* times = nullptr;
  std::size_t rows = 0, epochs = 0;
  double* moments = nullptr;
  std::size_t resume_from = 0;
  const double* prior_mean = nullptr;
};

/// The smoother's output of a block: rows x epochs x k means and standard deviations (NaN before
/// a row's start), and per row the log-likelihood of its observations given the first
/// (the prediction error decomposition; with a given prior, of all of them).
struct KalmanSmoothed {
  std::vector<double> mean, sd;
  std::vector<double> log_likelihood;
};

/// Forward filter (from `resume_from`) and RTS smoother over all epochs of every row.
KalmanSmoothed kalman_smooth(const KalmanParams& params, const KalmanBlock& block, const RunOptions& run = {});

/// The summed log-likelihood of the rows' observations (forward filter only, moments unused):
/// what `--process-noise auto` maximises over q. Summed in row order: the same bits for any
/// thread count.
double kalman_log_likelihood(const KalmanParams& params, const KalmanBlock& block, const RunOptions& run = {});

/// The variance of each M3C2 distance as an observation: (LOD / c)^2, c the critical value that
/// made the LOD (section 3.3): z at the confidence for --lod z and the bootstrap, Welch's t with
/// eq. (2)'s degrees of freedom for --lod t and auto (t when n1 or n2 < 30), from the standard
/// errors sigma_k / sqrt(n_k) as the engine computes them (exact for the mean and CloudCompare's
/// median LOD; for --lod t with the Maritz-Jarrett median, whose standard error the store does
/// not keep, an approximation: docs/series.md). NaN where the LOD or the counts are NaN / 0.
std::vector<double> lod_observation_variance(const Params& params, const double* lod, const double* sigma1,
                                             const double* n1, const double* sigma2, const double* n2,
                                             std::size_t count, const RunOptions& run = {});

}  // namespace m3c2
