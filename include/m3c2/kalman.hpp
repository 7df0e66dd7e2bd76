#pragma once
// A linear Kalman filter and Rauch-Tung-Striebel (RTS) smoother over each core point's M3C2
// distance series (docs/series.md, "Kalman filter"), after Winiwarter et al. (2023, "Full
// four-dimensional change analysis of topographic point cloud time series using Kalman
// filtering", Earth Surf. Dynam. 11: 593-613). The state of a core point is x = [d, d'] (the
// velocity model) or [d, d', d''] (the acceleration model), with the shared observation model also
// b, the reference cylinder's error that every epoch's distance shares (KalmanObservation); the
// epochs' times may be irregular. Rows of row-major
// [core point][epoch] arrays; NaN marks an epoch without an observation (predicted only).
// Every row is independent: the same bits for any thread count and any split into blocks.

#include <m3c2/params.hpp>
#include <m3c2/run_options.hpp>

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
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

/// What an epoch's distance observes (docs/series.md, "Kalman filter", where the model is derived).
/// Every epoch is compared with the same reference cylinder, whose mean over n1 points of a rough
/// surface errs by b ~ N(0, s^2 / n1): one error in every distance, which no filtering averages away.
/// kShared (the default): the state holds b (constant, no process noise), z_k = d_k + b + e_k,
/// e_k ~ N(0, s^2 / n2_k + reg^2) independent, s^2 the core point's scatter pooled over the reference
/// and its epochs (so an epoch with a distance but too few points for a LOD still observes); d = 0
/// at the reference's time anchors the change. kIndependent: z_k = d_k + e_k, e_k ~ N(0, r_k)
/// independent, r_k the block's `variance` (LOD / c)^2: the model of kalman4d and the tum-rsa
/// py4dgeo fork, over-confident where the reference is no denser than the epochs (the table in
/// docs/series.md, "Calibration").
enum class KalmanObservation : std::uint8_t { kShared, kIndependent };

/// The state's size: d, d' (d'') and, with the shared observation, b.
constexpr std::size_t kalman_state(KalmanModel m, KalmanObservation o) {
  return std::size_t(m) + (o == KalmanObservation::kShared ? 1 : 0);
}

/// Numbers per epoch of the filtered moments: the state's mean (n = kalman_state) and the
/// covariance's upper triangle (row by row: P00, P01, ..., P11, ...), b last.
constexpr std::size_t kalman_moments(KalmanModel m, KalmanObservation o) {
  const std::size_t n = kalman_state(m, o);
  return n + n * (n + 1) / 2;
}

struct KalmanParams {
  KalmanModel model = KalmanModel::kVelocity;
  KalmanNoise noise = KalmanNoise::kContinuous;
  double process_noise = 0.0;  ///< q >= 0 (see KalmanNoise), in the distances' unit and the times' unit
  /// Where a row's filter starts (the independent model; the shared one starts at its anchor,
  /// below). false (the default): at its first observed epoch, with
  /// d = that observation, var(d) = its variance, the derivatives 0 with the variances of
  /// `initial_variance` [1] and [2]. true: at time `prior_time` (before every epoch) with mean
  /// `prior_mean` (per row, or 0 when none is given) and covariance diag(initial_variance),
  /// predicted to the first epoch (how kalman4d anchors d = 0 at the reference epoch).
  bool prior_given = false;
  double prior_time = 0.0;
  /// Variances of d, d', d'' at the start ((unit / day)^2 for the rate): 1 for the derivatives,
  /// both references' P0 = I, large for geomorphic rates in metres (docs/series.md).
  std::array<double, 3> initial_variance{0.0, 1.0, 1.0};
  KalmanObservation observation = KalmanObservation::kShared;
  /// The shared model only. The reference's time in the times' unit, NaN when unknown; the
  /// epoch that is the reference file itself (the same SHA-256; -1 for none): its distance is
  /// the reference against itself (e_k = -b exactly), no observation, and its time is the
  /// reference's when `reference_time` is NaN. With the reference at or before the first epoch
  /// the filter starts there with d = 0 exactly; with none known, or after the first epoch, it
  /// starts at the first observation with d diffuse, so var(d) keeps b's s^2 / n1 (docs/series.md).
  double reference_time = std::numeric_limits<double>::quiet_NaN();
  std::int64_t reference_epoch = -1;
  double registration_error = 0.0;  ///< reg of eq. (1), one per epoch (each registered on its own)
  /// The shared model only: the false-alarm rate of the step test (docs/series.md, "Steps"). At
  /// each observed epoch t the generalised likelihood ratio of a jump of the level d just before t,
  /// from the innovations of t and of the next observed epoch (Willsky & Jones 1976), is compared
  /// with the chi-square(1) quantile at 1 - step_false_alarm; above it the jump's variance
  /// mu^2 - var(mu) (mu its estimated size) is added to var(d) before t's update, in the filter and
  /// the smoother alike. 0: no test (the smooth-motion model alone). The q of
  /// kalman_fit_process_noise is the smooth-motion model's (fitted without the test).
  double step_false_alarm = 1e-4;
  Variance spread = Variance::kSample;  ///< how the store's sigma1, sigma2 were made (Params::variance)
};

/// One block of core points. `values`, `variance`: rows x epochs (observation and its variance;
/// NaN in either: no observation). `times`: the epochs' times, non-decreasing, finite.
/// `moments`: rows x epochs x kalman_moments(model, observation), the filtered state at each epoch (NaN
/// before a row's start): the epochs before `resume_from` are read (kept from an earlier run on
/// the same epochs, parameters and observations; the independent model only: the shared one's
/// pooled scatter changes with every epoch), the others written. `prior_mean`: rows x k or null.
/// The shared model reads `sigma1`, `n1`, `sigma2`, `n2` (rows x epochs, the store's: NaN for none)
/// instead of `variance`.
struct KalmanBlock {
  const double* values = nullptr;
  const double* variance = nullptr;
  const double* times = nullptr;
  std::size_t rows = 0, epochs = 0;
  double* moments = nullptr;
  std::size_t resume_from = 0;
  const double* prior_mean = nullptr;
  const double* sigma1 = nullptr;
  const double* n1 = nullptr;
  const double* sigma2 = nullptr;
  const double* n2 = nullptr;
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

/// `--process-noise auto`: the q maximising kalman_log_likelihood without the step test (one q
/// for the scene, as the papers use one; step_false_alarm ignored), over log10 q: a grid of half
/// decades from 10^-8 to 10^4 times q0 = (median observation variance) / M00(median epoch
/// spacing), M00 the variance q = 1 adds to d over dt,
/// refined by golden section to 1e-3 decades. `edge`: -1 / +1 when the best grid point is the
/// smallest / largest tried, else 0. Throws when no two epochs differ in time or nothing is observed.
struct KalmanFit {
  double process_noise = 0.0;
  int edge = 0;
};
KalmanFit kalman_fit_process_noise(const KalmanParams& params, const KalmanBlock& block, const RunOptions& run = {});

/// Each row's observation variance at each epoch (NaN: no observation), as the filter uses it:
/// `variance` (independent), s^2 / n2 + reg^2 with the row's pooled s^2 (shared).
std::vector<double> kalman_observation_variance(const KalmanParams& params, const KalmanBlock& block,
                                                const RunOptions& run = {});

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
