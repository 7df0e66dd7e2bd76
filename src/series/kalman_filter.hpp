#pragma once
// The Kalman filter and RTS smoother's per-row templates (include/m3c2/kalman.hpp; docs/series.md,
// "Kalman filter"), shared by two translation units: kalman.cpp instantiates the independent
// observation model (K = N), kalman_shared.cpp the shared one (N = K + 1). Apart, each unit gets
// the inlining and constant-propagation it had alone: in one unit, the four instantiations made
// GCC outline the small solves, and the independent filter (the same arithmetic, the same bits)
// ran 30 % more instructions (callgrind, bench/kalman.py).
//
// The filter and smoother of a core point's distance series (Winiwarter et al. 2023, Earth Surf.
// Dynam. 11: 593, section 3.3). Textbook equations (Rauch,
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
// The shared model's step test (KalmanParams::step_false_alarm; docs/series.md, "Steps"): a jump
// of the level d just before an observed epoch t changes the innovation of t by 1 and that of the
// next observed epoch t' by g = H F(t' - t) (I - K_t H) e_d (the filter's response to it), so the
// generalised likelihood ratio of a jump of unknown size mu from these two innovations v, v'
// (variances S, S') is  Lambda = (v/S + g v'/S')^2 / I,  I = 1/S + g^2/S',  mu = (v/S + g v'/S') / I
// (Willsky & Jones 1976, IEEE Trans. Autom. Control 21: 108, with a window of two epochs;
// chi-square(1) without a jump). Where Lambda exceeds the quantile at 1 - alpha, the jump is taken
// as process noise of variance j = mu^2 - 1/I on d before t's update (the covariance matching of
// adaptive filtering, Mehra 1972, IEEE Trans. Autom. Control 17: 693; Bar-Shalom, Li &
// Kirubarajan 2001, 11.2), and the smoother's P-next holds the same j: the RTS pass stays the
// smoother of the model with those jumps.

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
#include <vector>

namespace m3c2::detail::kalman {
// Internal linkage, as the templates had in one unit: each unit's own copy, inlined as before
// (with external linkage GCC kept the update out of line: 5 % more instructions).
namespace {  // NOLINT(google-build-namespaces, cert-dcl59-cpp): a private header of two units

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

bool observed(const KalmanBlock& b, std::size_t r, std::size_t t) {
  const double z = b.values[r * b.epochs + t], v = b.variance[r * b.epochs + t];
  return std::isfinite(z) && std::isfinite(v) && v >= 0.0;
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

/// The chi-square(1) quantile at 1 - alpha that the step test's Lambda is compared with
/// (infinite, no test, for alpha = 0).
inline double step_threshold(double alpha) {
  if (!(alpha > 0.0)) return std::numeric_limits<double>::infinity();
  const double z = detail::z_critical(1.0 - alpha);
  return z * z;
}

/// The step test at observed epoch t of row r (shared model; the header's comment): x, P the
/// prediction at t, z and var t's observation. Returns j, the variance to add to var(d) before
/// t's update (0: no jump).
template <int K, int N>
double step_jump(const KalmanParams& p, const KalmanBlock& b, const SharedRow& row, std::size_t r, std::size_t t,
                 double threshold, double z, double var, const Vec<N>& x, const Mat<N>& P) {
  const Vec<N> ph = P.col(0) + P.col(N - 1);
  const double s = ph(0) + ph(N - 1) + var, v = z - x(0) - x(N - 1);
  double info = 1.0 / s, score = v / s;
  std::size_t next = t + 1;
  double next_var = kNaN;
  for (; next < b.epochs; ++next)
    if (!std::isnan(next_var = observation_variance(p, b, row, r, next))) break;
  if (next < b.epochs) {  // t's update without a jump, predicted to the next observation
    const Vec<N> gain = ph / s;
    Mat<N> a = Mat<N>::Identity();
    a.col(0) -= gain, a.col(N - 1) -= gain;
    Vec<N> xn = x + gain * v;
    Mat<N> pn = a * P * a.transpose() + (var * gain) * gain.transpose();
    symmetrize<N>(pn);
    for (std::size_t u = t + 1; u <= next; ++u) predict<K, N>(p, b.times[u] - b.times[u - 1], xn, pn);
    Vec<N> e = -gain;  // (I - K H) e_d
    e(0) += 1.0;
    const Vec<N> w = transition<K, N>(b.times[next] - b.times[t]) * e;
    const double g = w(0) + w(N - 1);
    const double s1 = pn(0, 0) + 2.0 * pn(0, N - 1) + pn(N - 1, N - 1) + next_var;
    const double v1 = b.values[r * b.epochs + next] - xn(0) - xn(N - 1);
    info += g * g / s1, score += g * v1 / s1;
  }
  if (!(score * score / info > threshold)) return 0.0;
  const double mu = score / info;
  return std::max(0.0, mu * mu - 1.0 / info);
}

/// The forward filter of row r from epoch `from` (the moments before it kept), writing the
/// moments of every later epoch (NaN before the row's start); returns the log-likelihood.
/// `jumps` (epochs, or null): the step test's j of each epoch (0 where none; shared model), for
/// the smoother; `threshold`: step_threshold(p.step_false_alarm).
template <int K, int N>
double forward(const KalmanParams& p, const KalmanBlock& b, std::size_t r, double* moments, double* jumps = nullptr,
               double threshold = std::numeric_limits<double>::infinity()) {
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
  if (jumps) std::fill_n(jumps, b.epochs, 0.0);
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
    // The independent model reads its variances directly (the former filter's hot loop, as fast).
    double var;
    if constexpr (N == K)
      var = b.variance[r * b.epochs + t];
    else
      var = observation_variance(p, b, row, r, t);
    const bool obs = N == K ? observed(b, r, t) : !std::isnan(var);
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
      if constexpr (N > K) {
        if (obs && threshold < std::numeric_limits<double>::infinity()) {
          const double j = step_jump<K, N>(p, b, row, r, t, threshold, z, var, x, P);
          P(0, 0) += j;
          if (jumps) jumps[t] = j;
        }
      }
      if (obs) ll += update<K, N>(z, var, x, P);
    }
    store<N>(x, P, moments + t * m);
  }
  return ll;
}

/// The RTS smoother of a row (its `moments`) over all its filtered epochs; writes d, d' (d'').
/// `jumps`: forward's (null: none).
template <int K, int N>
void backward(const KalmanParams& p, const KalmanBlock& b, const double* moments, double* mean, double* sd,
              const double* jumps = nullptr) {
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
      if (jumps) pp(0, 0) += jumps[t + 1];  // the step test's jump, as the filter added it
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

template <int K, int N>
KalmanSmoothed smooth_k(const KalmanParams& p, const KalmanBlock& b, const RunOptions& run) {
  constexpr std::size_t m = std::size_t(N) + std::size_t(N) * (N + 1) / 2;
  KalmanSmoothed out;
  out.mean.assign(b.rows * b.epochs * K, kNaN);
  out.sd.assign(b.rows * b.epochs * K, kNaN);
  out.log_likelihood.assign(b.rows, 0.0);
  const double threshold = N > K ? step_threshold(p.step_false_alarm) : std::numeric_limits<double>::infinity();
  const bool test = threshold < std::numeric_limits<double>::infinity();
  detail::parallel_blocks<std::vector<double>>(
      b.rows, run, [&](std::size_t begin, std::size_t end, std::vector<double>& jumps) {
        if (test) jumps.resize(b.epochs);
        double* j = test ? jumps.data() : nullptr;
        for (std::size_t r = begin; r < end; ++r) {
          double* moments = b.moments + r * b.epochs * m;
          out.log_likelihood[r] = forward<K, N>(p, b, r, moments, j, threshold);
          backward<K, N>(p, b, moments, out.mean.data() + r * b.epochs * K, out.sd.data() + r * b.epochs * K, j);
        }
      });
  return out;
}

template <int K, int N>
double likelihood_k(const KalmanParams& p, const KalmanBlock& b, const RunOptions& run) {
  std::vector<double> ll(b.rows, 0.0);
  const double threshold = N > K ? step_threshold(p.step_false_alarm) : std::numeric_limits<double>::infinity();
  detail::parallel_blocks<std::vector<double>>(
      b.rows, run, [&](std::size_t begin, std::size_t end, std::vector<double>& work) {
        constexpr std::size_t m = std::size_t(N) + std::size_t(N) * (N + 1) / 2;
        work.resize(b.epochs * m);
        KalmanBlock one = b;
        one.moments = work.data();
        one.resume_from = 0;
        for (std::size_t r = begin; r < end; ++r) ll[r] = forward<K, N>(p, one, r, work.data(), nullptr, threshold);
      });
  double total = 0.0;
  for (double v : ll) total += v;  // row order: the same bits for any thread count
  return total;
}

}  // namespace

/// The shared observation model's smoother and log-likelihood (kalman_shared.cpp).
KalmanSmoothed smooth_shared(const KalmanParams& p, const KalmanBlock& b, const RunOptions& run);
double likelihood_shared(const KalmanParams& p, const KalmanBlock& b, const RunOptions& run);

}  // namespace m3c2::detail::kalman
