// The Kalman filter and RTS smoother of a core point's distance series (include/m3c2/kalman.hpp;
// Winiwarter et al. 2023, Earth Surf. Dynam. 11: 593, section 3.3). Textbook equations (Rauch,
// Tung & Striebel 1965; Bar-Shalom, Li & Kirubarajan 2001, ch. 6 and 8 for the noise models):
//   predict  x- = F x,  P- = F P F^T + Q                 F = [[1, dt(, dt^2/2)], [0, 1(, dt)](, [0, 0, 1])]
//   update   S = P-00 + R,  K = P- H^T / S,  x = x- + K (z - x-0),  P = (I - K H) P- (I - K H)^T + K R K^T
//   smooth   C = P F^T (P-next)^-1,  xs = x + C (xs_next - F x),  Ps = P + C (Ps_next - P-next) C^T
// The update is Joseph's form (symmetric and positive semi-definite in floating point); the
// log-likelihood sums -(log(2 pi S) + v^2 / S) / 2 over the innovations v (Harvey 1989, 3.4).
// The shared observation model (KalmanObservation::kShared) appends b, the reference's error, to
// the state: F and Q leave it (constant), H = [1, 0, (0,) 1], so S = P00 + 2 P0b + Pbb + r and
// K = P H / S; the filter is otherwise the same code. The templates take K, the dynamic
// components, and N = K (independent) or K + 1 (shared), the state's size.

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
#include <utility>

namespace m3c2 {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

template <int K>
using Vec = Eigen::Matrix<double, K, 1>;
template <int K>
using Mat = Eigen::Matrix<double, K, K>;

/// F over the N-state: d, d' (d'') move, b (the shared model's last component) stays.
template <int K, int N>
Mat<N> transition(double dt) {
  Mat<N> f = Mat<N>::Identity();
  f(0, 1) = dt;
  if constexpr (K == 3) f(0, 2) = 0.5 * dt * dt, f(1, 2) = dt;
  return f;
}

/// Q = q M(dt) (KalmanNoise) on d, d' (d''); none on b (the reference's error does not change).
template <int K, int N>
Mat<N> process_noise(const KalmanParams& p, double dt) {
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
  if constexpr (N == K) {
    return q * m;
  } else {
    Mat<N> out = Mat<N>::Zero();
    out.template topLeftCorner<K, K>() = q * m;
    return out;
  }
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

/// The shared model's inputs of one row: the scatter s^2 pooled over the reference and the
/// epochs, and the reference's count n1. Each side's sum of squares about its own mean is
/// sigma^2 (n - 1) (sample spread; n for the population's), and the sides, samples of one rough
/// surface, share its variance, so the unbiased pooled estimate is
///   s^2 = [(n1 - 1) sigma1^2 + sum_k (n2_k - 1) sigma2_k^2] / [(n1 - 1) + sum_k (n2_k - 1)]
/// (a side with n = 1 adds nothing; the epoch that is the reference file is the reference again,
/// left out). No side with n >= 2: no scatter, no estimate. n1 is the reference cylinder's count,
/// the same at every epoch (one cylinder): its first finite value.
struct SharedRow {
  double scatter = kNaN, n1 = kNaN;
  bool usable() const { return std::isfinite(scatter) && n1 >= 1.0; }
};

SharedRow shared_row(const KalmanParams& p, const KalmanBlock& b, std::size_t r) {
  const double* n1 = b.n1 + r * b.epochs;
  const double* s1 = b.sigma1 + r * b.epochs;
  const double* n2 = b.n2 + r * b.epochs;
  const double* s2 = b.sigma2 + r * b.epochs;
  const double loss = p.spread == Variance::kSample ? 1.0 : 0.0;  // sigma^2 (n - loss) is the sum of squares
  SharedRow row;
  double squares = 0.0, dof = 0.0;
  for (std::size_t t = 0; t < b.epochs; ++t)
    if (std::isfinite(n1[t]) && n1[t] >= 1.0) {
      row.n1 = n1[t];
      if (n1[t] >= 2.0 && std::isfinite(s1[t])) squares += s1[t] * s1[t] * (n1[t] - loss), dof += n1[t] - 1.0;
      break;
    }
  for (std::size_t t = 0; t < b.epochs; ++t) {
    if (std::int64_t(t) == p.reference_epoch || !(n2[t] >= 2.0) || !std::isfinite(n2[t]) || !std::isfinite(s2[t]))
      continue;
    squares += s2[t] * s2[t] * (n2[t] - loss), dof += n2[t] - 1.0;
  }
  if (dof > 0.0) row.scatter = squares / dof;
  return row;
}

/// The observation variance of row r at epoch t, NaN when the epoch observes nothing there.
double observation_variance(const KalmanParams& p, const KalmanBlock& b, const SharedRow& row, std::size_t r,
                            std::size_t t) {
  const std::size_t i = r * b.epochs + t;
  if (!std::isfinite(b.values[i])) return kNaN;
  if (p.observation == KalmanObservation::kIndependent) {
    const double v = b.variance[i];
    return std::isfinite(v) && v >= 0.0 ? v : kNaN;
  }
  if (std::int64_t(t) == p.reference_epoch || !row.usable() || !(b.n2[i] >= 1.0) || !std::isfinite(b.n2[i]))
    return kNaN;
  return row.scatter / b.n2[i] + p.registration_error * p.registration_error;
}

/// The shared model's anchor: the reference's time (given, or the reference epoch's) when it is
/// at or before the first epoch; NaN (no anchor) otherwise (docs/series.md, "Kalman filter").
double anchor_time(const KalmanParams& p, const KalmanBlock& b) {
  if (b.epochs == 0) return kNaN;
  double t = p.reference_time;
  if (!std::isfinite(t) && p.reference_epoch >= 0) t = b.times[std::size_t(p.reference_epoch)];
  return std::isfinite(t) && t <= b.times[0] ? t : kNaN;
}

template <int K, int N>
void predict(const KalmanParams& p, double dt, Vec<N>& x, Mat<N>& P) {
  const Mat<N> f = transition<K, N>(dt);
  x = f * x;
  P = f * P * f.transpose() + process_noise<K, N>(p, dt);
  symmetrize<N>(P);
}

/// The update with observation z of variance r (H = [1, 0, ...] or, shared, [1, 0, ..., 1]);
/// returns the innovation's log-likelihood term.
template <int K, int N>
double update(double z, double r, Vec<N>& x, Mat<N>& P) {
  Mat<N> a = Mat<N>::Identity();
  double s, v;
  Vec<N> gain;
  if constexpr (N == K) {
    s = P(0, 0) + r, v = z - x(0);
    gain = P.col(0) / s;
    a.col(0) -= gain;
  } else {
    const Vec<N> ph = P.col(0) + P.col(N - 1);
    s = ph(0) + ph(N - 1) + r, v = z - x(0) - x(N - 1);
    gain = ph / s;
    a.col(0) -= gain, a.col(N - 1) -= gain;
  }
  x += gain * v;
  P = a * P * a.transpose() + (r * gain) * gain.transpose();
  symmetrize<N>(P);
  return -0.5 * (std::log(2.0 * std::numbers::pi * s) + v * v / s);
}

/// The state at a row's first observation z (variance r) when nothing precedes it. Independent:
/// d = z, var(d) = r. Shared without an anchor: d diffuse, so d + b = z +- r and b keeps its
/// prior N(0, vb): d = z, var(d) = vb + r, cov(d, b) = -vb (the diffuse prior's exact limit).
template <int K, int N>
void first_state(const KalmanParams& p, double z, double r, double vb, Vec<N>& x, Mat<N>& P) {
  x.setZero(), P.setZero();
  x(0) = z, P(0, 0) = r;
  for (int i = 1; i < K; ++i) P(i, i) = p.initial_variance[std::size_t(i)];
  if constexpr (N > K) P(0, 0) += vb, P(0, K) = P(K, 0) = -vb, P(K, K) = vb;
}

/// The forward filter of row r from epoch `from` (the moments before it kept), writing the
/// moments of every later epoch (NaN before the row's start); returns the log-likelihood.
template <int K, int N>
double forward(const KalmanParams& p, const KalmanBlock& b, std::size_t r, double* moments) {
  constexpr std::size_t m = std::size_t(N) + std::size_t(N) * (N + 1) / 2;
  SharedRow row;
  double vb = 0.0;
  if constexpr (N > K) {
    row = shared_row(p, b, r);
    if (!row.usable()) {  // no scatter: no variance for any observation, no estimate
      std::fill_n(moments, b.epochs * m, kNaN);
      return 0.0;
    }
    vb = row.scatter / row.n1;
  }
  Vec<N> x;
  Mat<N> P;
  bool started = false;
  double t_last = 0.0, ll = 0.0;
  if constexpr (N > K) {
    const double anchor = anchor_time(p, b);
    if (std::isfinite(anchor)) {  // d = 0 exactly at the reference's time, b ~ N(0, s^2 / n1)
      x.setZero(), P.setZero();
      for (int i = 1; i < K; ++i) P(i, i) = p.initial_variance[std::size_t(i)];
      P(K, K) = vb;
      started = true, t_last = anchor;
    }
  } else if (b.resume_from > 0 && std::isfinite(moments[(b.resume_from - 1) * m])) {
    load<N>(moments + (b.resume_from - 1) * m, x, P);
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
    const double var = observation_variance(p, b, row, r, t);
    const bool obs = !std::isnan(var);
    const double z = b.values[r * b.epochs + t];
    if (!started) {
      if (!obs) {
        std::fill_n(moments + t * m, m, kNaN);
        continue;
      }
      first_state<K, N>(p, z, var, vb, x, P);
      started = true, t_last = b.times[t];
    } else {
      predict<K, N>(p, b.times[t] - t_last, x, P);
      t_last = b.times[t];
      if (obs) ll += update<K, N>(z, var, x, P);
    }
    store<N>(x, P, moments + t * m);
  }
  return ll;
}

/// The RTS smoother of a row (its `moments`) over all its filtered epochs; writes d, d' (d'').
template <int K, int N>
void backward(const KalmanParams& p, const KalmanBlock& b, const double* moments, double* mean, double* sd) {
  constexpr std::size_t m = std::size_t(N) + std::size_t(N) * (N + 1) / 2;
  std::fill_n(mean, b.epochs * K, kNaN);
  std::fill_n(sd, b.epochs * K, kNaN);
  if (b.epochs == 0 || !std::isfinite(moments[(b.epochs - 1) * m])) return;  // never started
  Vec<N> xs, x;
  Mat<N> Ps, P;
  load<N>(moments + (b.epochs - 1) * m, xs, Ps);
  for (std::size_t t = b.epochs; t-- > 0;) {
    if (t + 1 < b.epochs) {
      if (!std::isfinite(moments[t * m])) break;  // before the row's start
      load<N>(moments + t * m, x, P);
      const double dt = b.times[t + 1] - b.times[t];
      const Mat<N> f = transition<K, N>(dt);
      Mat<N> pp = f * P * f.transpose() + process_noise<K, N>(p, dt);
      symmetrize<N>(pp);
      // C = P F^T pp^-1, solved (pp symmetric): C^T = pp^-1 F P.
      const Mat<N> c = pp.ldlt().solve(f * P).transpose();
      xs = x + c * (xs - f * x);
      Ps = P + c * (Ps - pp) * c.transpose();
      symmetrize<N>(Ps);
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
}

template <int K, int N>
KalmanSmoothed smooth_k(const KalmanParams& p, const KalmanBlock& b, const RunOptions& run) {
  constexpr std::size_t m = std::size_t(N) + std::size_t(N) * (N + 1) / 2;
  KalmanSmoothed out;
  out.mean.assign(b.rows * b.epochs * K, kNaN);
  out.sd.assign(b.rows * b.epochs * K, kNaN);
  out.log_likelihood.assign(b.rows, 0.0);
  detail::parallel_blocks<int>(b.rows, run, [&](std::size_t begin, std::size_t end, int&) {
    for (std::size_t r = begin; r < end; ++r) {
      double* moments = b.moments + r * b.epochs * m;
      out.log_likelihood[r] = forward<K, N>(p, b, r, moments);
      backward<K, N>(p, b, moments, out.mean.data() + r * b.epochs * K, out.sd.data() + r * b.epochs * K);
    }
  });
  return out;
}

template <int K, int N>
double likelihood_k(const KalmanParams& p, const KalmanBlock& b, const RunOptions& run) {
  std::vector<double> ll(b.rows, 0.0);
  detail::parallel_blocks<std::vector<double>>(
      b.rows, run, [&](std::size_t begin, std::size_t end, std::vector<double>& work) {
        constexpr std::size_t m = std::size_t(N) + std::size_t(N) * (N + 1) / 2;
        work.resize(b.epochs * m);
        KalmanBlock one = b;
        one.moments = work.data();
        one.resume_from = 0;
        for (std::size_t r = begin; r < end; ++r) ll[r] = forward<K, N>(p, one, r, work.data());
      });
  double total = 0.0;
  for (double v : ll) total += v;  // row order: the same bits for any thread count
  return total;
}

/// Calls f<K, N>() for the params' model and observation.
template <template <int, int> class F, class... A>
auto dispatch(const KalmanParams& p, A&&... a) {
  const bool shared = p.observation == KalmanObservation::kShared;
  if (p.model == KalmanModel::kAcceleration)
    return shared ? F<3, 4>::run(std::forward<A>(a)...) : F<3, 3>::run(std::forward<A>(a)...);
  return shared ? F<2, 3>::run(std::forward<A>(a)...) : F<2, 2>::run(std::forward<A>(a)...);
}

template <int K, int N>
struct Smooth {
  static KalmanSmoothed run(const KalmanParams& p, const KalmanBlock& b, const RunOptions& r) {
    return smooth_k<K, N>(p, b, r);
  }
};
template <int K, int N>
struct Likelihood {
  static double run(const KalmanParams& p, const KalmanBlock& b, const RunOptions& r) {
    return likelihood_k<K, N>(p, b, r);
  }
};

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
  return dispatch<Smooth>(params, params, block, run);
}

double kalman_log_likelihood(const KalmanParams& params, const KalmanBlock& block, const RunOptions& run) {
  KalmanBlock b = block;
  std::vector<double> none(1);
  if (!b.moments) b.moments = none.data();  // checked for presence only; each thread uses its own
  check(params, b);
  return dispatch<Likelihood>(params, params, b, run);
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
    throw InvalidArgument(
        "--process-noise auto needs at least two epochs at distinct times and observations "
        "with a variance; give --process-noise Q");
  const double u0 = std::log10(std::max(median(r), 1e-300) / unit_m00(params, median(dts)));
  const auto loglik = [&](double u) {
    KalmanParams p = params;
    p.process_noise = std::pow(10.0, u);
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
