// The public Kalman API (include/m3c2/kalman.hpp): input checks, the choice of the templates
// (series/kalman_filter.hpp, the equations and their references), the observation variances and
// the maximum-likelihood fit of q. The independent observation model is instantiated here, the
// shared one in kalman_shared.cpp (why apart: kalman_filter.hpp).

#include "series/kalman_filter.hpp"

#include <m3c2/errors.hpp>

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

namespace m3c2 {
namespace {

using namespace detail::kalman;

void check(const KalmanParams& p, const KalmanBlock& b) {
  if (!(p.process_noise >= 0.0) || !std::isfinite(p.process_noise))
    throw InvalidArgument("the process noise must be finite and >= 0, got " + std::to_string(p.process_noise));
  for (double v : p.initial_variance)
    if (!(v >= 0.0) || !std::isfinite(v)) throw InvalidArgument("the initial variances must be finite and >= 0");
  const bool shared = p.observation == KalmanObservation::kShared;
  if (b.rows > 0 && b.epochs > 0 && (!b.values || !b.times || !b.moments))
    throw InvalidArgument("a Kalman block needs values, times and moments");
  if (b.rows > 0 && b.epochs > 0 && !shared && !b.variance)
    throw InvalidArgument("the independent observation model needs each observation's variance");
  if (b.rows > 0 && b.epochs > 0 && shared && (!b.sigma1 || !b.n1 || !b.sigma2 || !b.n2))
    throw InvalidArgument("the shared observation model needs sigma1, n1, sigma2 and n2");
  if (b.resume_from > b.epochs) throw InvalidArgument("resume_from is past the last epoch");
  for (std::size_t t = 0; t < b.epochs; ++t) {
    if (!std::isfinite(b.times[t])) throw InvalidArgument("every epoch needs a time (epoch " + std::to_string(t) + ")");
    if (t > 0 && b.times[t] < b.times[t - 1])
      throw InvalidArgument("the epochs' times must not decrease (epoch " + std::to_string(t) + ")");
  }
  if (p.prior_given && b.epochs > 0 && !(p.prior_time <= b.times[0]))
    throw InvalidArgument("the prior's time must not be after the first epoch");
  if (!shared) return;
  // The pooled scatter changes with every epoch added: a shared run is always from scratch.
  if (b.resume_from != 0) throw InvalidArgument("the shared observation model does not resume (resume_from must be 0)");
  if (p.prior_given) throw InvalidArgument("the shared observation model starts at the reference: give no prior");
  if (!(p.registration_error >= 0.0) || !std::isfinite(p.registration_error))
    throw InvalidArgument("the registration error must be finite and >= 0");
  if (p.reference_epoch < -1 || (p.reference_epoch >= 0 && std::size_t(p.reference_epoch) >= b.epochs))
    throw InvalidArgument("reference_epoch must be -1 or an epoch of the block");
  if (std::isinf(p.reference_time)) throw InvalidArgument("the reference's time must be finite or NaN (unknown)");
  if (!(p.step_false_alarm >= 0.0 && p.step_false_alarm < 1.0))
    throw InvalidArgument("the step test's false-alarm rate must be in [0, 1), got " +
                          std::to_string(p.step_false_alarm));
}

double median(std::vector<double> v) {
  const std::size_t n = v.size(), h = n / 2;
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(h), v.end());
  const double upper = v[h];
  if (n % 2) return upper;
  return 0.5 * (*std::max_element(v.begin(), v.begin() + std::ptrdiff_t(h)) + upper);
}

/// M(dt)[0, 0] of Q = q M(dt): the variance q = 1 adds to d over dt.
double unit_m00(const KalmanParams& p, double dt) {
  if (p.noise == KalmanNoise::kDiscrete) return 0.25 * std::pow(dt, 4);
  return p.model == KalmanModel::kVelocity ? dt * dt * dt / 3.0 : std::pow(dt, 5) / 20.0;
}

}  // namespace

KalmanSmoothed kalman_smooth(const KalmanParams& params, const KalmanBlock& block, const RunOptions& run) {
  check(params, block);
  if (params.observation == KalmanObservation::kShared) return smooth_shared(params, block, run);
  return params.model == KalmanModel::kAcceleration ? smooth_k<3, 3>(params, block, run)
                                                    : smooth_k<2, 2>(params, block, run);
}

double kalman_log_likelihood(const KalmanParams& params, const KalmanBlock& block, const RunOptions& run) {
  KalmanBlock b = block;
  std::vector<double> none(1);
  if (!b.moments) b.moments = none.data();  // checked for presence only; each thread uses its own
  check(params, b);
  if (params.observation == KalmanObservation::kShared) return likelihood_shared(params, b, run);
  return params.model == KalmanModel::kAcceleration ? likelihood_k<3, 3>(params, b, run)
                                                    : likelihood_k<2, 2>(params, b, run);
}

std::vector<double> kalman_observation_variance(const KalmanParams& params, const KalmanBlock& block,
                                                const RunOptions& run) {
  KalmanBlock b = block;
  std::vector<double> none(1);
  if (!b.moments) b.moments = none.data();
  check(params, b);
  std::vector<double> out(b.rows * b.epochs, kNaN);
  const bool shared = params.observation == KalmanObservation::kShared;
  detail::parallel_blocks<int>(b.rows, run, [&](std::size_t begin, std::size_t end, int&) {
    for (std::size_t r = begin; r < end; ++r) {
      const SharedRow row = shared ? shared_row(params, b, r) : SharedRow{};
      for (std::size_t t = 0; t < b.epochs; ++t) out[r * b.epochs + t] = observation_variance(params, b, row, r, t);
    }
  });
  return out;
}

KalmanFit kalman_fit_process_noise(const KalmanParams& params, const KalmanBlock& block, const RunOptions& run) {
  std::vector<double> dts;
  for (std::size_t t = 1; t < block.epochs; ++t)
    if (block.times[t] - block.times[t - 1] > 0.0) dts.push_back(block.times[t] - block.times[t - 1]);
  std::vector<double> r;
  for (double v : kalman_observation_variance(params, block, run))
    if (std::isfinite(v)) r.push_back(v);
  if (dts.empty() || r.empty())
    throw InvalidArgument(std::string("--process-noise auto needs ") +
                          (r.empty() ? "observations with a variance, and no core point has a distance with one"
                                     : "at least two epochs at distinct times") +
                          "; give --process-noise Q");
  const double u0 = std::log10(std::max(median(r), 1e-300) / unit_m00(params, median(dts)));
  const auto loglik = [&](double u) {
    KalmanParams p = params;
    p.process_noise = std::pow(10.0, u);
    // q is the smooth motion's: fitted without the step test, whose yes / no decisions would make
    // the likelihood jump with q (more jumps, each a gain, at the q that provokes them).
    p.step_false_alarm = 0.0;
    return kalman_log_likelihood(p, block, run);
  };
  constexpr double kFrom = -8.0, kTo = 4.0, kStep = 0.5, kTolerance = 1e-3;  // decades of q around q0
  std::vector<double> grid, scores;
  for (std::size_t i = 0;; ++i) {
    const double u = (u0 + kFrom) + double(i) * kStep;
    if (u > u0 + kTo + 1e-9) break;
    grid.push_back(u), scores.push_back(loglik(u));
  }
  std::size_t best = grid.size();
  for (std::size_t i = 0; i < grid.size(); ++i)
    if (!std::isnan(scores[i]) && (best == grid.size() || scores[i] > scores[best])) best = i;
  if (best == grid.size()) throw InvalidArgument("--process-noise auto: the likelihood is NaN at every q tried");
  KalmanFit fit;
  fit.edge = best == 0 ? -1 : best + 1 == grid.size() ? 1 : 0;
  double lo = grid[best > 0 ? best - 1 : 0], hi = grid[std::min(grid.size() - 1, best + 1)];
  const double g = (std::sqrt(5.0) - 1.0) / 2.0;
  double a = hi - g * (hi - lo), c = lo + g * (hi - lo);
  double fa = loglik(a), fc = loglik(c);
  while (hi - lo > kTolerance) {
    if (fa > fc) {
      hi = c, c = a, fc = fa;
      a = hi - g * (hi - lo);
      fa = loglik(a);
    } else {
      lo = a, a = c, fa = fc;
      c = lo + g * (hi - lo);
      fc = loglik(c);
    }
  }
  // The best of the grid's and the section's ends (on a tie the larger q, as before).
  std::pair<double, double> top{scores[best], grid[best]};
  for (const auto& e : {std::pair{fa, a}, std::pair{fc, c}}) top = std::max(top, e);
  fit.process_noise = std::pow(10.0, top.second);
  return fit;
}

std::vector<double> lod_observation_variance(const Params& params, const double* lod, const double* sigma1,
                                             const double* n1, const double* sigma2, const double* n2,
                                             std::size_t count, const RunOptions& run) {
  std::vector<double> out(count, kNaN);
  const double z = detail::z_critical(params.confidence);
  detail::parallel_blocks<int>(
      count, run,
      [&](std::size_t begin, std::size_t end, int&) {
        for (std::size_t i = begin; i < end; ++i) {
          if (!std::isfinite(lod[i])) continue;
          double critical = z;
          if (params.lod == Lod::kT || params.lod == Lod::kAuto) {
            // The counts as the engine saw them (stored exactly, as integers); the standard errors
            // as central_spread() makes them: sigma / sqrt(n), the same operations.
            if (!(n1[i] >= 2.0) || !(n2[i] >= 2.0) || !std::isfinite(sigma1[i]) || !std::isfinite(sigma2[i])) continue;
            const auto a = std::uint32_t(n1[i]), b = std::uint32_t(n2[i]);
            const double se1 = sigma1[i] / std::sqrt(double(a)), se2 = sigma2[i] / std::sqrt(double(b));
            critical = detail::critical_value(params, z, se1, a, se2, b);
          }
          const double s = lod[i] / critical;
          out[i] = s * s;
        }
      },
      4096);
  return out;
}

}  // namespace m3c2
