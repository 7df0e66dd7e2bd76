// The Kalman filter and RTS smoother (include/m3c2/kalman.hpp) against hand-derived values, the
// closed-form weighted least-squares line (the smoother's limit with no process noise and a
// diffuse rate), the same bits for any thread count and a resumed run, and the observation
// variance against the critical values it must invert; the shared observation model by hand (its
// anchor, pooled scatter and reference epoch), its thread invariance and the ML fit of q. The GLS
// oracles for q > 0 (both models) and the numpy filter are in tests/python/series/test_kalman.py
// and test_kalman_shared.py.

#include <m3c2/kalman.hpp>

#include "test_support.hpp"
#include "uncertainty/confidence.hpp"

#include <cmath>
#include <random>
#include <vector>

namespace m3c2::test {
namespace {

/// Runs the independent observation model (the references'; the tests below written for it).
KalmanSmoothed run(KalmanParams p, const std::vector<double>& z, const std::vector<double>& var,
                   const std::vector<double>& t, std::size_t rows, std::vector<double>& moments, int threads = 1,
                   std::size_t resume_from = 0) {
  p.observation = KalmanObservation::kIndependent;
  KalmanBlock b;
  b.values = z.data(), b.variance = var.data(), b.times = t.data();
  b.rows = rows, b.epochs = t.size(), b.moments = moments.data(), b.resume_from = resume_from;
  RunOptions opts;
  opts.threads = threads;
  return kalman_smooth(p, b, opts);
}

TEST(Kalman, TwoObservationsByHand) {
  // q = 0: x0 = [z0, 0], P0 = diag(r0, V); predicted P = [[r0 + V dt^2, V dt], [V dt, V]];
  // the filtered d1 = z0 + (r0 + V dt^2) / S (z1 - z0), S = r0 + V dt^2 + r1; with two epochs
  // the smoother's last epoch is the filter's, and its first follows from the RTS gain.
  KalmanParams p;
  p.process_noise = 0.0;
  p.initial_variance = {0.0, 4.0, 0.0};
  const std::vector<double> z{1.0, 3.0}, var{0.25, 1.0}, t{0.0, 0.5};
  std::vector<double> moments(2 * 5);
  const KalmanSmoothed s = run(p, z, var, t, 1, moments);
  const double V = 4.0, dt = 0.5, r0 = 0.25, r1 = 1.0, S = r0 + V * dt * dt + r1;
  const double d1 = 1.0 + (r0 + V * dt * dt) / S * 2.0, v1 = (V * dt) / S * 2.0;
  EXPECT_NEAR(s.mean[2], d1, 1e-14);
  EXPECT_NEAR(s.mean[3], v1, 1e-14);
  // q = 0 and a deterministic line: the smoothed state at epoch 0 is the smoothed one at 1
  // carried back by the model, d0 = d1 - v1 dt, rate v1.
  EXPECT_NEAR(s.mean[0], d1 - v1 * dt, 1e-14);
  EXPECT_NEAR(s.mean[1], v1, 1e-14);
  const double p00 = (r0 + V * dt * dt) * r1 / S;  // filtered var(d1)
  EXPECT_NEAR(s.sd[2], std::sqrt(p00), 1e-14);
  // The log-likelihood of z1 given z0: innovation 2, variance S.
  EXPECT_NEAR(s.log_likelihood[0], -0.5 * (std::log(2.0 * M_PI * S) + 4.0 / S), 1e-14);
}

TEST(Kalman, NoProcessNoiseIsTheWeightedLineFit) {
  // q = 0 and a diffuse rate: the smoothed d at every epoch is the weighted least-squares line
  // (weights 1 / r) evaluated there, and the smoothed rate its slope (closed form below).
  std::mt19937_64 rng(7);
  std::normal_distribution<double> noise(0.0, 1.0);
  const std::size_t n = 12;
  std::vector<double> t(n), z(n), var(n);
  double tk = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    tk += 0.3 + 0.2 * double(k % 3);  // irregular
    t[k] = tk;
    var[k] = 0.01 * (1.0 + double(k % 4));
    z[k] = 0.5 + 0.8 * tk + std::sqrt(var[k]) * noise(rng);
  }
  z[5] = std::nan("");  // a missing epoch: predicted only
  KalmanParams p;
  p.process_noise = 0.0;
  p.initial_variance = {0.0, 1e8, 0.0};
  std::vector<double> moments(n * 5);
  const KalmanSmoothed s = run(p, z, var, t, 1, moments);
  double sw = 0, st = 0, sz = 0, stt = 0, stz = 0;
  for (std::size_t k = 0; k < n; ++k) {
    if (std::isnan(z[k])) continue;
    const double w = 1.0 / var[k];
    sw += w, st += w * t[k], sz += w * z[k], stt += w * t[k] * t[k], stz += w * t[k] * z[k];
  }
  const double slope = (sw * stz - st * sz) / (sw * stt - st * st), icpt = (sz - slope * st) / sw;
  for (std::size_t k = 0; k < n; ++k) {
    EXPECT_NEAR(s.mean[2 * k], icpt + slope * t[k], 1e-6) << "epoch " << k;
    EXPECT_NEAR(s.mean[2 * k + 1], slope, 1e-6) << "epoch " << k;
  }
  // The slope's standard error: sqrt(sum w / (sum w sum w t^2 - (sum w t)^2)).
  EXPECT_NEAR(s.sd[1], std::sqrt(sw / (sw * stt - st * st)), 1e-6);
}

TEST(Kalman, SameBitsForAnyThreadCountAndResumed) {
  std::mt19937_64 rng(11);
  std::normal_distribution<double> noise(0.0, 1.0);
  const std::size_t rows = 1000, n = 40;
  std::vector<double> t(n), z(rows * n), var(rows * n);
  // Irregular times and variances: a resumed run must find the very covariance the filter held
  // (an asymmetric one, rounded differently on each side, is stored as its upper triangle only).
  std::uniform_real_distribution<double> spread(0.01, 0.09);
  for (std::size_t k = 0; k < n; ++k) t[k] = double(k) + 0.25 * double(k % 2) + 0.1 * double(k % 5);
  for (std::size_t r = 0; r < rows; ++r)
    for (std::size_t k = 0; k < n; ++k) {
      var[r * n + k] = spread(rng);
      z[r * n + k] = (r % 7 == 0 && k < 10) ? std::nan("") : 0.01 * double(r % 13) * t[k] + 0.2 * noise(rng);
    }
  for (KalmanModel model : {KalmanModel::kVelocity, KalmanModel::kAcceleration}) {
    KalmanParams p;
    p.model = model;
    p.process_noise = 0.01;
    const std::size_t m = kalman_moments(model, KalmanObservation::kIndependent);
    std::vector<double> m1(rows * n * m), m4(rows * n * m);
    const KalmanSmoothed a = run(p, z, var, t, rows, m1, 1), b = run(p, z, var, t, rows, m4, 4);
    EXPECT_TRUE(BitIdentical(a.mean, b.mean));
    EXPECT_TRUE(BitIdentical(a.sd, b.sd));
    EXPECT_TRUE(BitIdentical(m1, m4));
    // Resumed at epoch 25 from the moments of a run on the first 25 epochs only.
    const std::size_t cut = 25;
    std::vector<double> zc, vc, tc(t.begin(), t.begin() + cut);
    for (std::size_t r = 0; r < rows; ++r) {
      zc.insert(zc.end(), z.begin() + r * n, z.begin() + r * n + cut);
      vc.insert(vc.end(), var.begin() + r * n, var.begin() + r * n + cut);
    }
    std::vector<double> mc(rows * cut * m);
    run(p, zc, vc, tc, rows, mc, 2);
    std::vector<double> resumed(rows * n * m, -1.0);
    for (std::size_t r = 0; r < rows; ++r)
      std::copy(mc.begin() + r * cut * m, mc.begin() + (r + 1) * cut * m, resumed.begin() + r * n * m);
    const KalmanSmoothed c = run(p, z, var, t, rows, resumed, 3, cut);
    EXPECT_TRUE(BitIdentical(a.mean, c.mean));
    EXPECT_TRUE(BitIdentical(a.sd, c.sd));
  }
}

TEST(Kalman, RefusesBadInput) {
  KalmanParams p;
  p.process_noise = -1.0;
  const std::vector<double> z{1.0, 2.0}, var{1.0, 1.0}, t{0.0, 1.0}, back{1.0, 0.0};
  std::vector<double> moments(10);
  EXPECT_THROW(run(p, z, var, t, 1, moments), InvalidArgument);
  p.process_noise = 1.0;
  EXPECT_THROW(run(p, z, var, back, 1, moments), InvalidArgument);
}

TEST(Kalman, ObservationVarianceInvertsTheLod) {
  Params p;
  p.confidence = 0.95;
  p.lod = Lod::kZ;
  const std::vector<double> lod{0.1, std::nan(""), 0.3}, s1{0.2, 0.2, 0.5}, n1{10, 10, 4}, s2{0.1, 0.1, 0.4},
      n2{50, 50, 5};
  auto v = lod_observation_variance(p, lod.data(), s1.data(), n1.data(), s2.data(), n2.data(), 3);
  EXPECT_NEAR(v[0], std::pow(0.1 / 1.959963984540054, 2), 1e-16);
  EXPECT_TRUE(std::isnan(v[1]));
  p.lod = Lod::kAuto;  // n1 = 10 < 30: Welch t (eq. 2) from sigma / sqrt(n)
  v = lod_observation_variance(p, lod.data(), s1.data(), n1.data(), s2.data(), n2.data(), 3);
  const double se1 = 0.5 / std::sqrt(4.0), se2 = 0.4 / std::sqrt(5.0);
  const double dof = std::pow(se1 * se1 + se2 * se2, 2) / (std::pow(se1, 4) / 3.0 + std::pow(se2, 4) / 4.0);
  EXPECT_NEAR(v[2], std::pow(0.3 / detail::t_critical(0.95, dof), 2), 1e-15);
  EXPECT_GT(detail::t_critical(0.95, dof), 2.3);  // a t, not z
}

/// One row of the shared model: distances z, the reference's (sigma1, n1), each epoch's (sigma2, n2).
struct SharedRow {
  std::vector<double> z, s1, n1, s2, n2;
};

KalmanSmoothed run_shared(const KalmanParams& p, const SharedRow& row, const std::vector<double>& t,
                          std::size_t rows = 1, int threads = 1) {
  KalmanBlock b;
  b.values = row.z.data(), b.times = t.data(), b.rows = rows, b.epochs = t.size();
  b.sigma1 = row.s1.data(), b.n1 = row.n1.data(), b.sigma2 = row.s2.data(), b.n2 = row.n2.data();
  std::vector<double> moments(rows * t.size() * kalman_moments(p.model, p.observation));
  b.moments = moments.data();
  RunOptions opts;
  opts.threads = threads;
  return kalman_smooth(p, b, opts);
}

TEST(KalmanShared, OneEpochAnchoredAtTheReferenceByHand) {
  // q = 0, a zero rate variance: d stays 0 from the reference's time, so one epoch observes
  // z = 0 + b + e with b ~ N(0, s^2/n1), e ~ N(0, s^2/n2 + reg^2): the smoothed d is 0, sd 0.
  // With a rate of prior variance V and dt: d = v dt, var(d) = V dt^2 a priori, and the update
  // gives E[d | z] = V dt^2 / S z, var = V dt^2 - (V dt^2)^2 / S, S = V dt^2 + s^2/n1 + r.
  // The pooled scatter: ((n1 - 1) sigma1^2 + (n2 - 1) sigma2^2) / (n1 + n2 - 2).
  KalmanParams p;
  p.process_noise = 0.0;
  p.initial_variance = {0.0, 4.0, 0.0};
  p.reference_time = -0.5;
  p.registration_error = 0.1;
  const SharedRow row{{0.3}, {0.2}, {5.0}, {0.4}, {3.0}};
  const KalmanSmoothed s = run_shared(p, row, {0.0});
  const double s2 = (4.0 * 0.04 + 2.0 * 0.16) / 6.0, vb = s2 / 5.0, r = s2 / 3.0 + 0.01;
  const double vd = 4.0 * 0.25, S = vd + vb + r;
  EXPECT_NEAR(s.mean[0], vd / S * 0.3, 1e-15);
  EXPECT_NEAR(s.sd[0], std::sqrt(vd - vd * vd / S), 1e-15);
  EXPECT_NEAR(s.mean[1], 4.0 * 0.5 / S * 0.3, 1e-15);  // the rate: cov(v, z) = V dt
  EXPECT_NEAR(s.log_likelihood[0], -0.5 * (std::log(2.0 * M_PI * S) + 0.09 / S), 1e-15);
}

TEST(KalmanShared, WithoutAnAnchorTheChangeKeepsTheReferencesError) {
  // No reference time: d diffuse, so one epoch gives d = z with var(d) = s^2/n1 + r (b unknown).
  KalmanParams p;
  p.process_noise = 0.0;
  const SharedRow row{{0.3}, {0.2}, {5.0}, {0.4}, {3.0}};
  const KalmanSmoothed s = run_shared(p, row, {2.0});
  const double s2 = (4.0 * 0.04 + 2.0 * 0.16) / 6.0;
  EXPECT_NEAR(s.mean[0], 0.3, 1e-15);
  EXPECT_NEAR(s.sd[0], std::sqrt(s2 / 5.0 + s2 / 3.0), 1e-15);
  // A reference time after the first epoch is no anchor either.
  p.reference_time = 3.0;
  EXPECT_NEAR(run_shared(p, row, {2.0}).sd[0], std::sqrt(s2 / 5.0 + s2 / 3.0), 1e-15);
}

TEST(KalmanShared, TheReferenceEpochIsNoObservationButGivesTheAnchor) {
  KalmanParams p;
  p.process_noise = 0.01;
  p.reference_epoch = 0;
  const std::vector<double> t{0.0, 1.0, 2.5, 3.0};
  SharedRow row{
      {0.0, 0.1, 0.25, std::nan("")}, {0.2, 0.2, 0.2, 0.2}, {6, 6, 6, 6}, {0.2, 0.3, std::nan(""), 0.1}, {6, 4, 1, 5}};
  const KalmanSmoothed a = run_shared(p, row, t);
  EXPECT_EQ(a.mean[0], 0.0);  // d = 0 exactly at the reference
  EXPECT_EQ(a.sd[0], 0.0);
  EXPECT_TRUE(std::isfinite(a.mean[3 * 2]));  // epoch 3 (no distance): predicted
  // Epoch 0's distance and spread (the reference against itself) change nothing.
  row.z[0] = 5.0, row.s2[0] = 9.0;
  const KalmanSmoothed b = run_shared(p, row, t);
  EXPECT_TRUE(BitIdentical(a.mean, b.mean));
  EXPECT_TRUE(BitIdentical(a.sd, b.sd));
  // An epoch with one point (no sigma2, n2 = 1) still observes: its distance moves the estimate.
  row.z[2] = 0.5;
  EXPECT_GT(run_shared(p, row, t).mean[2 * 2], a.mean[2 * 2] + 0.01);
  // No side with two points: no scatter, no estimate.
  const SharedRow none{{0.1, 0.2}, {std::nan(""), std::nan("")}, {1, 1}, {std::nan(""), std::nan("")}, {1, 1}};
  KalmanParams q;
  EXPECT_TRUE(std::isnan(run_shared(q, none, {0.0, 1.0}).mean[0]));
}

TEST(KalmanShared, SameBitsForAnyThreadCountAndTheFitFindsTheSimulatedNoise) {
  // Truth: a random walk of the rate (continuous white acceleration, q = 1e-4) from d = 0 at the
  // reference; the ML q of 300 rows must be within a factor 2 of it, the same for 1 and 4 threads.
  std::mt19937_64 rng(5);
  std::normal_distribution<double> g(0.0, 1.0);
  const std::size_t rows = 300, n = 30;
  const double q = 1e-4, sigma = 0.02;
  std::vector<double> t(n);
  for (std::size_t k = 0; k < n; ++k) t[k] = 1.0 + double(k) + 0.3 * double(k % 3);
  SharedRow all;
  for (std::size_t r = 0; r < rows; ++r) {
    const int n1 = 8;
    double b = 0.0, ss = 0.0;
    std::vector<double> x(n1);
    for (double& v : x) v = sigma * g(rng), b += v / n1;
    for (double v : x) ss += (v - b) * (v - b);
    double d = 0.0, rate = 0.0, t_last = 0.0;
    for (std::size_t k = 0; k < n; ++k) {
      const double dt = t[k] - t_last;  // exact discretisation of the continuous model
      const double a = std::sqrt(q * dt * dt * dt / 12.0) * g(rng), c = std::sqrt(q * dt) * g(rng);
      d += rate * dt + c * dt / 2.0 + a, rate += c, t_last = t[k];
      const int n2 = 3 + int(k % 5);
      double e = 0.0, s2 = 0.0;
      std::vector<double> y(static_cast<std::size_t>(n2));
      for (double& v : y) v = sigma * g(rng), e += v / n2;
      for (double v : y) s2 += (v - e) * (v - e);
      all.z.push_back(d + e - b), all.n2.push_back(n2), all.s2.push_back(std::sqrt(s2 / (n2 - 1)));
      all.n1.push_back(n1), all.s1.push_back(std::sqrt(ss / (n1 - 1)));
    }
  }
  KalmanParams p;
  p.reference_time = 0.0;
  KalmanBlock b;
  b.values = all.z.data(), b.times = t.data(), b.rows = rows, b.epochs = n;
  b.sigma1 = all.s1.data(), b.n1 = all.n1.data(), b.sigma2 = all.s2.data(), b.n2 = all.n2.data();
  RunOptions one, four;
  one.threads = 1, four.threads = 4;
  const KalmanFit f1 = kalman_fit_process_noise(p, b, one), f4 = kalman_fit_process_noise(p, b, four);
  EXPECT_EQ(f1.process_noise, f4.process_noise);
  EXPECT_EQ(f1.edge, 0);
  EXPECT_GT(f1.process_noise, q / 2);
  EXPECT_LT(f1.process_noise, q * 2);
  p.process_noise = f1.process_noise;
  const KalmanSmoothed a = run_shared(p, all, t, rows, 1), c = run_shared(p, all, t, rows, 4);
  EXPECT_TRUE(BitIdentical(a.mean, c.mean));
  EXPECT_TRUE(BitIdentical(a.sd, c.sd));
}

TEST(KalmanShared, RefusesToResumeAndMissingSpreads) {
  KalmanParams p;
  const std::vector<double> z{1.0, 2.0}, t{0.0, 1.0};
  std::vector<double> moments(2 * kalman_moments(p.model, p.observation));
  KalmanBlock b;
  b.values = z.data(), b.times = t.data(), b.rows = 1, b.epochs = 2, b.moments = moments.data();
  EXPECT_THROW(kalman_smooth(p, b), InvalidArgument);  // no sigma / n
  b.sigma1 = b.n1 = b.sigma2 = b.n2 = z.data();
  b.resume_from = 1;
  EXPECT_THROW(kalman_smooth(p, b), InvalidArgument);
}

}  // namespace
}  // namespace m3c2::test
