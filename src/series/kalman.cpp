// The Kalman filter and RTS smoother of a core point's distance series (include/m3c2/kalman.hpp;
// Winiwarter et al. 2023, Earth Surf. Dynam. 11: 593, section 3.3). Textbook equations (Rauch,
// Tung & Striebel 1965; Bar-Shalom, Li & Kirubarajan 2001, ch. 6 and 8 for the noise models):
//   predict  x- = F x,  P- = F P F^T + Q                 F = [[1, dt(, dt^2/2)], [0, 1(, dt)](, [0, 0, 1])]
//   update   S = P-00 + R,  K = P- H^T / S,  x = x- + K (z - x-0),  P = (I - K H) P- (I - K H)^T + K R K^T
//   smooth   C = P F^T (P-next)^-1,  xs = x + C (xs_next - F x),  Ps = P + C (Ps_next - P-next) C^T
// The update is Joseph's form (symmetric and positive semi-definite in floating point); the
// log-likelihood sums -(log(2 pi S) + v^2 / S) / 2 over the innovations v (Harvey 1989, 3.4).

#include <m3c2/errors.hpp>
#include <m3c2/kalman.hpp>

#include "support/parallel_for.hpp"
#include "uncertainty/confidence.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

namespace m3c2 {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

template <int K>
using Vec = Eigen::Matrix<double, K, 1>;
template <int K>
using Mat = Eigen::Matrix<double, K, K>;

template <int K>
Mat<K> transition(double dt) {
  Mat<K> f = Mat<K>::Identity();
  f(0, 1) = dt;
  if constexpr (K == 3) f(0, 2) = 0.5 * dt * dt, f(1, 2) = dt;
  return f;
}

/// Q = q M(dt) (KalmanNoise).
template <int K>
Mat<K> process_noise(const KalmanParams& p, double dt) {
  Mat<K> m;
  const double q = p.process_noise, d2 = dt * dt, d3 = d2 * dt;
  if (p.noise == KalmanNoise::kDiscrete) {
    Vec<K> g;
    if constexpr (K == 2)
      g << 0.5 * d2, dt;
    else
      g << 0.5 * d2, dt, 1.0;
    m = g * g.transpose();
  } else if constexpr (K == 2) {
    m << d3 / 3.0, d2 / 2.0, d2 / 2.0, dt;
  } else {
    const double d4 = d3 * dt, d5 = d4 * dt;
    m << d5 / 20.0, d4 / 8.0, d3 / 6.0, d4 / 8.0, d3 / 3.0, d2 / 2.0, d3 / 6.0, d2 / 2.0, dt;
  }
  return q * m;
}

/// M made exactly symmetric, (M + M^T) / 2 element by element: the moments keep the upper
/// triangle only, so a resumed run must find the very matrix the filter held (the same bits).
/// (`M = (M + M.transpose()) / 2` would alias: Eigen reads M(j, i) after writing M(i, j).)
template <int K>
void symmetrize(Mat<K>& m) {
  for (int i = 0; i < K; ++i)
    for (int j = i + 1; j < K; ++j) m(i, j) = m(j, i) = 0.5 * (m(i, j) + m(j, i));
}

template <int K>
void store(const Vec<K>& x, const Mat<K>& P, double* out) {
  for (int i = 0; i < K; ++i) out[i] = x(i);
  double* tri = out + K;
  for (int i = 0; i < K; ++i)
    for (int j = i; j < K; ++j) *tri++ = P(i, j);
}

template <int K>
void load(const double* in, Vec<K>& x, Mat<K>& P) {
  for (int i = 0; i < K; ++i) x(i) = in[i];
  const double* tri = in + K;
  for (int i = 0; i < K; ++i)
    for (int j = i; j < K; ++j) P(i, j) = P(j, i) = *tri++;
}

bool observed(const KalmanBlock& b, std::size_t r, std::size_t t) {
  const double z = b.values[r * b.epochs + t], v = b.variance[r * b.epochs + t];
  return std::isfinite(z) && std::isfinite(v) && v >= 0.0;
}

template <int K>
void predict(const KalmanParams& p, double dt, Vec<K>& x, Mat<K>& P) {
  const Mat<K> f = transition<K>(dt);
  x = f * x;
  P = f * P * f.transpose() + process_noise<K>(p, dt);
  symmetrize<K>(P);
}

/// The update with observation z of variance r; returns the innovation's log-likelihood term.
template <int K>
double update(double z, double r, Vec<K>& x, Mat<K>& P) {
  const double s = P(0, 0) + r, v = z - x(0);
  const Vec<K> gain = P.col(0) / s;
  Mat<K> a = Mat<K>::Identity();
  a.col(0) -= gain;
  x += gain * v;
  P = a * P * a.transpose() + (r * gain) * gain.transpose();
  symmetrize<K>(P);
  return -0.5 * (std::log(2.0 * std::numbers::pi * s) + v * v / s);
}

/// The forward filter of row r from epoch `from` (the moments before it kept), writing the
/// moments of every later epoch (NaN before the row's start); returns the log-likelihood.
template <int K>
double forward(const KalmanParams& p, const KalmanBlock& b, std::size_t r, double* moments) {
  constexpr std::size_t m = std::size_t(K) + std::size_t(K) * (K + 1) / 2;
  Vec<K> x;
  Mat<K> P;
  bool started = false;
  double t_last = 0.0, ll = 0.0;
  if (b.resume_from > 0 && std::isfinite(moments[(b.resume_from - 1) * m])) {
    load<K>(moments + (b.resume_from - 1) * m, x, P);
    started = true, t_last = b.times[b.resume_from - 1];
  } else if (b.resume_from == 0 && p.prior_given) {
    x.setZero();
    if (b.prior_mean)
      for (int i = 0; i < K; ++i) x(i) = b.prior_mean[r * K + i];
    P.setZero();
    for (int i = 0; i < K; ++i) P(i, i) = p.initial_variance[std::size_t(i)];
    started = true, t_last = p.prior_time;
  }
  for (std::size_t t = b.resume_from; t < b.epochs; ++t) {
    const bool obs = observed(b, r, t);
    const double z = b.values[r * b.epochs + t], var = b.variance[r * b.epochs + t];
    if (!started) {
      if (!obs) {
        std::fill_n(moments + t * m, m, kNaN);
        continue;
      }
      x.setZero(), P.setZero();
      x(0) = z, P(0, 0) = var;
      for (int i = 1; i < K; ++i) P(i, i) = p.initial_variance[std::size_t(i)];
      started = true, t_last = b.times[t];
    } else {
      predict<K>(p, b.times[t] - t_last, x, P);
      t_last = b.times[t];
      if (obs) ll += update<K>(z, var, x, P);
    }
    store<K>(x, P, moments + t * m);
  }
  return ll;
}

/// The RTS smoother of a row (its `moments`) over all its filtered epochs.
template <int K>
void backward(const KalmanParams& p, const KalmanBlock& b, const double* moments, double* mean, double* sd) {
  constexpr std::size_t m = std::size_t(K) + std::size_t(K) * (K + 1) / 2;
  std::fill_n(mean, b.epochs * K, kNaN);
  std::fill_n(sd, b.epochs * K, kNaN);
  if (b.epochs == 0 || !std::isfinite(moments[(b.epochs - 1) * m])) return;  // never started
  Vec<K> xs, x;
  Mat<K> Ps, P;
  load<K>(moments + (b.epochs - 1) * m, xs, Ps);
  for (std::size_t t = b.epochs; t-- > 0;) {
    if (t + 1 < b.epochs) {
      if (!std::isfinite(moments[t * m])) break;  // before the row's start
      load<K>(moments + t * m, x, P);
      const double dt = b.times[t + 1] - b.times[t];
      const Mat<K> f = transition<K>(dt);
      Mat<K> pp = f * P * f.transpose() + process_noise<K>(p, dt);
      symmetrize<K>(pp);
      // C = P F^T pp^-1, solved (pp symmetric): C^T = pp^-1 F P.
      const Mat<K> c = pp.ldlt().solve(f * P).transpose();
      xs = x + c * (xs - f * x);
      Ps = P + c * (Ps - pp) * c.transpose();
      symmetrize<K>(Ps);
    }
    for (int i = 0; i < K; ++i) {
      mean[t * K + i] = xs(i);
      sd[t * K + i] = std::sqrt(std::max(0.0, Ps(i, i)));
    }
  }
}

void check(const KalmanParams& p, const KalmanBlock& b) {
  if (!(p.process_noise >= 0.0) || !std::isfinite(p.process_noise))
    throw InvalidArgument("the process noise must be finite and >= 0, got " + std::to_string(p.process_noise));
  for (double v : p.initial_variance)
    if (!(v >= 0.0) || !std::isfinite(v)) throw InvalidArgument("the initial variances must be finite and >= 0");
  if (b.rows > 0 && b.epochs > 0 && (!b.values || !b.variance || !b.times || !b.moments))
    throw InvalidArgument("a Kalman block needs values, variances, times and moments");
  if (b.resume_from > b.epochs) throw InvalidArgument("resume_from is past the last epoch");
  for (std::size_t t = 0; t < b.epochs; ++t) {
    if (!std::isfinite(b.times[t])) throw InvalidArgument("every epoch needs a time (epoch " + std::to_string(t) + ")");
    if (t > 0 && b.times[t] < b.times[t - 1])
      throw InvalidArgument("the epochs' times must not decrease (epoch " + std::to_string(t) + ")");
  }
  if (p.prior_given && b.epochs > 0 && !(p.prior_time <= b.times[0]))
    throw InvalidArgument("the prior's time must not be after the first epoch");
}

template <int K>
KalmanSmoothed smooth_k(const KalmanParams& p, const KalmanBlock& b, const RunOptions& run) {
  constexpr std::size_t m = std::size_t(K) + std::size_t(K) * (K + 1) / 2;
  KalmanSmoothed out;
  out.mean.assign(b.rows * b.epochs * K, kNaN);
  out.sd.assign(b.rows * b.epochs * K, kNaN);
  out.log_likelihood.assign(b.rows, 0.0);
  detail::parallel_blocks<int>(b.rows, run, [&](std::size_t begin, std::size_t end, int&) {
    for (std::size_t r = begin; r < end; ++r) {
      double* moments = b.moments + r * b.epochs * m;
      out.log_likelihood[r] = forward<K>(p, b, r, moments);
      backward<K>(p, b, moments, out.mean.data() + r * b.epochs * K, out.sd.data() + r * b.epochs * K);
    }
  });
  return out;
}

template <int K>
double likelihood_k(const KalmanParams& p, const KalmanBlock& b, const RunOptions& run) {
  std::vector<double> ll(b.rows, 0.0);
  detail::parallel_blocks<std::vector<double>>(
      b.rows, run, [&](std::size_t begin, std::size_t end, std::vector<double>& work) {
        constexpr std::size_t m = std::size_t(K) + std::size_t(K) * (K + 1) / 2;
        work.resize(b.epochs * m);
        KalmanBlock one = b;
        one.moments = work.data();
        one.resume_from = 0;
        for (std::size_t r = begin; r < end; ++r) ll[r] = forward<K>(p, one, r, work.data());
      });
  double total = 0.0;
  for (double v : ll) total += v;  // row order: the same bits for any thread count
  return total;
}

}  // namespace

KalmanSmoothed kalman_smooth(const KalmanParams& params, const KalmanBlock& block, const RunOptions& run) {
  check(params, block);
  return params.model == KalmanModel::kAcceleration ? smooth_k<3>(params, block, run) : smooth_k<2>(params, block, run);
}

double kalman_log_likelihood(const KalmanParams& params, const KalmanBlock& block, const RunOptions& run) {
  KalmanBlock b = block;
  std::vector<double> none(1);
  if (!b.moments) b.moments = none.data();  // checked for presence only; each thread uses its own
  check(params, b);
  return params.model == KalmanModel::kAcceleration ? likelihood_k<3>(params, b, run) : likelihood_k<2>(params, b, run);
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
