// CANUPO features (multi-scale dimensionality, include/m3c2/dimensionality.hpp) against a
// straightforward reference: per point and per scale a nanoflann radius search, the covariance
// of the neighbours (two passes) and Eigen's SelfAdjointEigenSolver, on the same thread count.
// Built only with -DM3C2_BUILD_BENCH=ON (needs nanoflann: apt-get install libnanoflann-dev):
//   cmake -S . -B build/bench -DM3C2_BUILD_BENCH=ON -DM3C2_BUILD_TESTS=OFF && cmake --build build/bench -j2
//   build/bench/bench/dimensionality_bench [points=1000000] [threads=2]
// The scene (seeded, derived, not real data): a rough ground of 100 m x 100 m with shrubs and
// trees as 3D scatter, ~80 % of the points on the ground; 10 scales 0.25 to 2.5 m.

#include <m3c2/dimensionality.hpp>

#include <nanoflann.hpp>

#include <Eigen/Eigenvalues>

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <random>
#include <vector>

namespace {

std::vector<double> scene(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  const double size = 100.0;
  auto height = [](double x, double y) {
    return 0.6 * std::sin(x / 2.0) * std::cos(y / 2.0) + 0.2 * std::sin(x * 1.4 + 1) * std::cos(y * 1.4) +
           0.05 * std::sin(x * 4.8) * std::cos(y * 4.8 + 2);
  };
  std::vector<double> xyz;
  xyz.reserve(3 * n);
  const std::size_t ground = n * 4 / 5;
  for (std::size_t i = 0; i < ground; ++i) {
    const double x = size * u(rng), y = size * u(rng);
    xyz.insert(xyz.end(), {x, y, height(x, y) + 0.02 * g(rng)});
  }
  while (xyz.size() < 3 * n) {  // blobs of 0.3 to 2.5 m, 200 to 4000 points
    const double cx = size * u(rng), cy = size * u(rng), r = 0.3 + 2.2 * u(rng) * u(rng);
    const std::size_t m = std::min<std::size_t>(n - xyz.size() / 3, std::size_t(200 + 3800 * u(rng)));
    const double base = height(cx, cy) + r;
    for (std::size_t k = 0; k < m; ++k) {
      double v[3] = {g(rng), g(rng), g(rng)};
      const double s = r * std::cbrt(u(rng)) / std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
      xyz.insert(xyz.end(), {cx + s * v[0], cy + s * v[1], base + s * v[2]});
    }
  }
  return xyz;
}

struct Adaptor {
  const std::vector<double>& xyz;
  std::size_t kdtree_get_point_count() const { return xyz.size() / 3; }
  double kdtree_get_pt(std::size_t i, std::size_t d) const { return xyz[3 * i + d]; }
  template <class B>
  bool kdtree_get_bbox(B&) const {
    return false;
  }
};
using Tree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, Adaptor>, Adaptor, 3, std::uint32_t>;

/// The reference: proportions [i][k][3] (descending), NaN with fewer than 3 neighbours.
std::vector<double> reference(const std::vector<double>& xyz, const std::vector<double>& diameters, int threads) {
  Adaptor adaptor{xyz};
  Tree tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  tree.buildIndex();
  const std::size_t n = xyz.size() / 3, s = diameters.size();
  std::vector<double> out(n * s * 3, std::nan(""));
#pragma omp parallel num_threads(threads)
  {
    std::vector<std::pair<std::uint32_t, double>> found;  // nanoflann 1.4 (Debian 12)
    nanoflann::SearchParams params;
    params.sorted = false;
#pragma omp for schedule(dynamic, 256)
    for (std::int64_t i = 0; i < std::int64_t(n); ++i) {
      const double* q = &xyz[3 * i];
      for (std::size_t k = 0; k < s; ++k) {
        const double r = 0.5 * diameters[k];
        const std::size_t m = tree.radiusSearch(q, r * r, found, params);
        if (m < 3) continue;
        Eigen::Vector3d mean = Eigen::Vector3d::Zero();
        for (const auto& f : found) mean += Eigen::Vector3d(&xyz[3 * f.first]);
        mean /= double(m);
        Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
        for (const auto& f : found) {
          const Eigen::Vector3d v = Eigen::Vector3d(&xyz[3 * f.first]) - mean;
          c.noalias() += v * v.transpose();
        }
        const Eigen::Vector3d e =
            Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(c, Eigen::EigenvaluesOnly).eigenvalues().cwiseMax(0.0);
        for (int j = 0; j < 3; ++j) out[(i * s + k) * 3 + j] = e(2 - j) / e.sum();
      }
    }
  }
  return out;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

int main(int argc, char** argv) {
  const std::size_t n = argc > 1 ? std::strtoull(argv[1], nullptr, 10) : 1000000;
  const int threads = argc > 2 ? std::atoi(argv[2]) : 2;
  std::vector<double> diameters;
  for (int k = 1; k <= 10; ++k) diameters.push_back(0.25 * k);
  const std::vector<double> xyz = scene(n, 18);
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  std::printf(
      "dimensionality bench: %zu points (seeded synthetic scene, 100 m x 100 m, ~%.0f points/m2 "
      "on the ground), %zu scales 0.25..2.5 m, %d threads, every point a core point\n",
      n, 0.8 * n / 1e4, diameters.size(), threads);

  m3c2::RunOptions run;
  run.threads = threads;
  auto t0 = std::chrono::steady_clock::now();
  std::clock_t c0 = std::clock();
  const m3c2::DimensionalityResult ours = m3c2::dimensionality({xyz.data(), n}, {xyz.data(), n}, diameters, 3, run);
  const double t_ours = seconds_since(t0), c_ours = double(std::clock() - c0) / CLOCKS_PER_SEC;
  t0 = std::chrono::steady_clock::now();
  c0 = std::clock();
  const std::vector<double> ref = reference(xyz, diameters, threads);
  const double t_ref = seconds_since(t0), c_ref = double(std::clock() - c0) / CLOCKS_PER_SEC;

  // Same features where both have >= 3 neighbours (ours fills smaller scales from larger ones).
  double worst = 0.0;
  std::size_t compared = 0, neighbours = 0;
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t k = 0; k < diameters.size(); ++k) {
      neighbours += ours.count[i * diameters.size() + k];
      if (ours.count[i * diameters.size() + k] < 3 || std::isnan(ref[(i * diameters.size() + k) * 3])) continue;
      ++compared;
      for (int j = 0; j < 3; ++j)
        worst = std::max(worst, std::abs(ours.proportions[(i * diameters.size() + k) * 3 + j] -
                                         ref[(i * diameters.size() + k) * 3 + j]));
    }
  std::printf("mean neighbours per point and scale: %.1f\n", double(neighbours) / double(n * diameters.size()));
  std::printf("octree (m3c2::dimensionality, index included): %8.2f s  %10.0f points/s  (CPU %.2f s)\n", t_ours,
              n / t_ours, c_ours);
  std::printf("reference (nanoflann + Eigen, index included): %8.2f s  %10.0f points/s  (CPU %.2f s)\n", t_ref,
              n / t_ref, c_ref);
  std::printf(
      "speed-up: %.2fx wall, %.2fx CPU; largest |difference| of the eigenvalue shares over %zu (point, scale) pairs: "
      "%.2e\n",
      t_ref / t_ours, c_ref / c_ours, compared, worst);
  return 0;
}
