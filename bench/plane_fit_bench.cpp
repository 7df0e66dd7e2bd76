// Throwaway timing of the plane fit: closed form (fit_plane) against Eigen's iterative solver
// (fit_plane_iterative) on co-moments of noisy planar neighbourhoods of ~30 points (workload
// W1's size), plus their largest disagreement. Not part of the build or of the tests; build by hand:
//   g++ -O3 -DNDEBUG -std=c++20 -ffp-contract=off -Iinclude -Isrc -I/usr/include/eigen3
//       bench/plane_fit_bench.cpp src/pipeline/plane_fit.cpp -o /tmp/plane_fit_bench && /tmp/plane_fit_bench

#include "pipeline/plane_fit.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <random>
#include <vector>

using m3c2::detail::PlaneFit;

int main() {
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::normal_distribution<double> g;
  std::vector<Eigen::Matrix3d> mats;
  for (int t = 0; t < 100000; ++t) {
    const Eigen::Vector3d n = Eigen::Vector3d(0.2 * g(rng), 0.2 * g(rng), 1.0).normalized();
    const Eigen::Vector3d e1 = n.unitOrthogonal(), e2 = n.cross(e1);
    std::vector<Eigen::Vector3d> pts;
    while (pts.size() < 30) {
      const double x = u(rng), y = u(rng);
      if (x * x + y * y <= 1.0) pts.push_back(x * e1 + y * e2 + 0.02 * g(rng) * n);
    }
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& p : pts) mean += p;
    mean /= double(pts.size());
    Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
    for (const auto& p : pts) c += (p - mean) * (p - mean).transpose();
    mats.push_back(c);
  }
  double max_angle = 0.0, max_dl = 0.0;
  for (const auto& a : mats) {
    const PlaneFit f = m3c2::detail::fit_plane(a), r = m3c2::detail::fit_plane_iterative(a);
    max_angle = std::max(max_angle, f.normal.cross(r.normal).norm());
    max_dl = std::max(max_dl, (f.eigenvalues - r.eigenvalues).cwiseAbs().maxCoeff() / r.eigenvalues(2));
  }
  std::printf("max |sin angle| %.3g, max |d lambda| / lambda2 %.3g\n", max_angle, max_dl);
  for (int rep = 0; rep < 5; ++rep) {
    for (int which = 0; which < 2; ++which) {
      double sink = 0.0;
      const auto t0 = std::chrono::steady_clock::now();
      for (const auto& a : mats) {
        const PlaneFit f = which ? m3c2::detail::fit_plane_iterative(a) : m3c2::detail::fit_plane(a);
        sink += f.normal(0) + f.eigenvalues(0);
      }
      const double ns = std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count();
      std::printf("%s %.1f ns/fit (sink %g)\n", which ? "iterative  " : "closed form", ns / double(mats.size()), sink);
    }
  }
}
