// The least work of an M3C2 run, timed on the machine that times m3c2 (docs/performance.md,
// "Lower bound"): per core point, a brute-force gather over a uniform cell grid of the exact
// neighbours within the normal sphere (radius D / 2) of the reference, their first and second
// moments summed in one pass (10 sums) and one plane fit (the engine's closed form); then, along
// that normal, the points of each cloud inside the projection cylinder (radius d / 2, |t| <= depth)
// gathered the same way and their count, sum of t and sum of t^2 summed. No canonical order, no
// multi-scale, no uncertainty: what any M3C2 must at least do with these inputs. The grids are
// built by a counting sort, side by side on the threads (timed apart), and the core points
// visited in cell order (not timed).
//
// Built with -DM3C2_BUILD_BENCH=ON (target lower_bound_bench), or by hand:
//   g++ -O3 -DNDEBUG -std=c++20 -fopenmp -ffp-contract=off -Iinclude -Isrc -I/usr/include/eigen3
//       bench/lower_bound_bench.cpp src/pipeline/plane_fit.cpp -o /tmp/lower_bound_bench
// Run: lower_bound_bench REF.npy CMP.npy CORE.npy D d DEPTH THREADS [REPEAT [engine]]   (float64 (n, 3) .npy)
// D = 0: vertical normals (no sphere). Prints one JSON line (seconds: best of REPEAT; cpu_*: CPU
// seconds of the process, user + system, every thread). With `engine`, m3c2::compute on the same
// inputs (min_points 1) is timed too, and a hash of its output columns' bits printed: the
// engine's own check that a change of speed left the results alone.

#include "pipeline/plane_fit.hpp"

#include <m3c2/m3c2.hpp>

#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <sys/resource.h>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace {

/// A float64 (n, 3) C-order .npy file (format 1.0 or 2.0).
std::vector<double> read_npy(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error("cannot open " + path);
  char magic[8];
  f.read(magic, 8);
  if (std::memcmp(magic, "\x93NUMPY", 6) != 0) throw std::runtime_error(path + " is not a .npy file");
  std::uint32_t header_len = 0;
  if (magic[6] == 1) {
    unsigned char b[2];
    f.read(reinterpret_cast<char*>(b), 2);
    header_len = b[0] | b[1] << 8;
  } else {
    unsigned char b[4];
    f.read(reinterpret_cast<char*>(b), 4);
    header_len = b[0] | b[1] << 8 | b[2] << 16 | std::uint32_t(b[3]) << 24;
  }
  std::string header(header_len, ' ');
  f.read(header.data(), header_len);
  if (header.find("'<f8'") == std::string::npos || header.find("'fortran_order': False") == std::string::npos)
    throw std::runtime_error(path + ": expected a C-order float64 array");
  const auto begin = f.tellg();
  f.seekg(0, std::ios::end);
  const auto bytes = std::size_t(f.tellg() - begin);
  f.seekg(begin);
  std::vector<double> v(bytes / sizeof(double));
  f.read(reinterpret_cast<char*>(v.data()), std::streamsize(v.size() * sizeof(double)));
  return v;
}

/// Points sorted into a dense grid of cubic cells (counting sort), coordinates copied in cell order.
struct Grid {
  double side = 1.0;
  std::array<double, 3> lo{};
  std::array<std::int64_t, 3> dims{};
  std::vector<std::uint32_t> start;  // per cell, then the end
  std::vector<double> xyz;           // in cell order

  Grid(const std::vector<double>& p, double wanted_side) {
    const std::size_t n = p.size() / 3;
    std::array<double, 3> hi{};
    for (int a = 0; a < 3; ++a) lo[a] = hi[a] = n ? p[a] : 0.0;
    for (std::size_t i = 0; i < n; ++i)
      for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], p[3 * i + a]), hi[a] = std::max(hi[a], p[3 * i + a]);
    side = wanted_side;
    // At most ~2^26 cells: larger cells where the extent asks for more (sparse, wide clouds).
    for (;;) {
      for (int a = 0; a < 3; ++a) dims[a] = std::int64_t((hi[a] - lo[a]) / side) + 1;
      if (double(dims[0]) * double(dims[1]) * double(dims[2]) <= double(1 << 26)) break;
      side *= 1.25;
    }
    start.assign(std::size_t(dims[0] * dims[1] * dims[2]) + 1, 0);
    std::vector<std::uint32_t> cell(n);
    for (std::size_t i = 0; i < n; ++i) cell[i] = std::uint32_t(index_of(&p[3 * i])), ++start[cell[i] + 1];
    for (std::size_t c = 1; c < start.size(); ++c) start[c] += start[c - 1];
    std::vector<std::uint32_t> next(start.begin(), start.end() - 1);
    xyz.resize(3 * n);
    for (std::size_t i = 0; i < n; ++i) std::memcpy(&xyz[3 * std::size_t(next[cell[i]]++)], &p[3 * i], 24);
  }
  std::int64_t coord(double x, int a) const {
    return std::clamp<std::int64_t>(std::int64_t(std::floor((x - lo[a]) / side)), 0, dims[a] - 1);
  }
  std::size_t index_of(const double* q) const {
    return std::size_t((coord(q[2], 2) * dims[1] + coord(q[1], 1)) * dims[0] + coord(q[0], 0));
  }
  /// Calls f(point) for every point of the cells meeting the box [lo, hi].
  template <class F>
  void for_box(const double* box_lo, const double* box_hi, F&& f) const {
    const std::int64_t x0 = coord(box_lo[0], 0), x1 = coord(box_hi[0], 0);
    for (std::int64_t z = coord(box_lo[2], 2); z <= coord(box_hi[2], 2); ++z)
      for (std::int64_t y = coord(box_lo[1], 1); y <= coord(box_hi[1], 1); ++y) {
        const std::size_t row = std::size_t((z * dims[1] + y) * dims[0]);
        for (std::uint32_t s = start[row + x0]; s < start[row + x1 + 1]; ++s) f(&xyz[3 * std::size_t(s)]);
      }
  }
};

double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

/// CPU seconds (user + system) of this process so far, all threads: the figure that holds on a
/// loaded machine, where a wall time counts the waits for a core.
double cpu_now() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 8) {
    std::fprintf(stderr, "usage: %s REF.npy CMP.npy CORE.npy D d DEPTH THREADS [REPEAT]\n", argv[0]);
    return 2;
  }
  const auto ref = read_npy(argv[1]), cmp = read_npy(argv[2]), core_in = read_npy(argv[3]);
  const double D = std::stod(argv[4]), d = std::stod(argv[5]), depth = std::stod(argv[6]);
  const int threads = std::stoi(argv[7]), repeat = argc > 8 ? std::stoi(argv[8]) : 3;
  const bool engine = argc > 9 && std::string(argv[9]) == "engine";
#ifdef _OPENMP
  omp_set_num_threads(threads);
#endif
  const double R = 0.5 * D, r = 0.5 * d;
  double t_build = 1e300, cpu_build = 1e300;
  // Cells of half the radius: the box of a sphere then covers about (2R + R/2)^2 of a surface
  // instead of (3R)^2 with cells of R.
  const double sphere_cell = 0.5 * (R > 0.0 ? R : r);
  // The three grids are independent: built side by side, one per thread (a serial build made
  // the bound's build phase up to three times what the least work takes on 2 threads).
  std::optional<Grid> grids[3];
  for (int k = 0; k < repeat; ++k) {
    for (auto& g : grids) g.reset();
    const double t0 = now(), c0 = cpu_now();
#pragma omp parallel for schedule(dynamic, 1)
    for (int g = 0; g < 3; ++g) grids[g].emplace(g == 2 ? cmp : ref, g == 0 ? sphere_cell : r);
    t_build = std::min(t_build, now() - t0), cpu_build = std::min(cpu_build, cpu_now() - c0);
  }
  const Grid &sphere_grid = *grids[0], &ref_grid = *grids[1], &cmp_grid = *grids[2];
  // Core points in the sphere grid's cell order: consecutive queries share their cells.
  const std::size_t m = core_in.size() / 3;
  std::vector<std::pair<std::size_t, std::uint32_t>> by_cell(m);
  for (std::size_t i = 0; i < m; ++i) by_cell[i] = {sphere_grid.index_of(&core_in[3 * i]), std::uint32_t(i)};
  std::sort(by_cell.begin(), by_cell.end());
  std::vector<double> core(3 * m);
  for (std::size_t i = 0; i < m; ++i) std::memcpy(&core[3 * i], &core_in[3 * by_cell[i].second], 24);

  std::vector<double> normal(3 * m), out(3 * m);
  double t_normals = 1e300, t_cylinders = 1e300, neighbours = 0.0, in_cylinders = 0.0;
  double cpu_normals = 1e300, cpu_cylinders = 1e300;
  for (int rep = 0; rep < repeat; ++rep) {
    double t0 = now(), c0 = cpu_now(), count_sum = 0.0;
    if (R > 0.0) {
#pragma omp parallel for schedule(dynamic, 64) reduction(+ : count_sum)
      for (std::int64_t i = 0; i < std::int64_t(m); ++i) {
        const double* q = &core[3 * i];
        const double box_lo[3] = {q[0] - R, q[1] - R, q[2] - R}, box_hi[3] = {q[0] + R, q[1] + R, q[2] + R};
        double s[10] = {};
        const double R2 = R * R;
        sphere_grid.for_box(box_lo, box_hi, [&](const double* p) {
          const double x = p[0] - q[0], y = p[1] - q[1], z = p[2] - q[2];
          const double keep = x * x + y * y + z * z <= R2 ? 1.0 : 0.0;  // no branch per point
          s[0] += keep, s[1] += keep * x, s[2] += keep * y, s[3] += keep * z;
          s[4] += keep * x * x, s[5] += keep * x * y, s[6] += keep * x * z;
          s[7] += keep * y * y, s[8] += keep * y * z, s[9] += keep * z * z;
        });
        count_sum += s[0];
        Eigen::Vector3d nv(0.0, 0.0, 1.0);
        if (s[0] >= 3.0) {
          const Eigen::Vector3d mean(s[1] / s[0], s[2] / s[0], s[3] / s[0]);
          Eigen::Matrix3d cm;
          cm << s[4], s[5], s[6], s[5], s[7], s[8], s[6], s[8], s[9];
          cm -= s[0] * mean * mean.transpose();
          const auto fit = m3c2::detail::fit_plane(cm);
          if (!fit.degenerate) nv = fit.normal;
        }
        for (int a = 0; a < 3; ++a) normal[3 * i + a] = nv(a);
      }
    } else {
      for (std::size_t i = 0; i < m; ++i) normal[3 * i] = 0.0, normal[3 * i + 1] = 0.0, normal[3 * i + 2] = 1.0;
    }
    t_normals = std::min(t_normals, now() - t0), cpu_normals = std::min(cpu_normals, cpu_now() - c0);
    neighbours = count_sum / double(m);
    t0 = now(), c0 = cpu_now();
    double cyl_sum = 0.0;
#pragma omp parallel for schedule(dynamic, 64) reduction(+ : cyl_sum)
    for (std::int64_t i = 0; i < std::int64_t(m); ++i) {
      const double* q = &core[3 * i];
      const double* n = &normal[3 * i];
      double box_lo[3], box_hi[3];
      for (int a = 0; a < 3; ++a) {
        const double reach = depth * std::abs(n[a]) + r * std::sqrt(std::max(0.0, 1.0 - n[a] * n[a]));
        box_lo[a] = q[a] - reach, box_hi[a] = q[a] + reach;
      }
      double mean_t[2];
      for (int cloud = 0; cloud < 2; ++cloud) {
        double s0 = 0.0, s1 = 0.0, s2 = 0.0;
        (cloud ? cmp_grid : ref_grid).for_box(box_lo, box_hi, [&](const double* p) {
          const double x = p[0] - q[0], y = p[1] - q[1], z = p[2] - q[2];
          const double t = x * n[0] + y * n[1] + z * n[2];
          const double wx = x - t * n[0], wy = y - t * n[1], wz = z - t * n[2];
          const double keep = (std::abs(t) <= depth && wx * wx + wy * wy + wz * wz <= r * r) ? 1.0 : 0.0;
          s0 += keep, s1 += keep * t, s2 += keep * t * t;
        });
        cyl_sum += s0;
        mean_t[cloud] = s1 / s0;
        out[3 * i + 1 + cloud] = s2;
      }
      out[3 * i] = mean_t[1] - mean_t[0];
    }
    t_cylinders = std::min(t_cylinders, now() - t0), cpu_cylinders = std::min(cpu_cylinders, cpu_now() - c0);
    in_cylinders = cyl_sum / double(2 * m);
  }
  double sink = 0.0;
  for (const double x : out) sink += std::isfinite(x) ? x : 0.0;
  double t_engine = 0.0, cpu_engine = 0.0;
  std::uint64_t hash = 0;
  if (engine) {
    m3c2::Params params;
    if (D > 0.0)
      params.normal_diameters = {D};
    else
      params.normal_source = m3c2::NormalSource::kVertical;
    params.projection_diameter = d, params.max_depth = depth, params.min_points = 1;
    m3c2::RunOptions run;
    run.threads = threads;
    const m3c2::PointsView a(ref.data(), ref.size() / 3), b(cmp.data(), cmp.size() / 3), q(core_in.data(), m);
    t_engine = cpu_engine = 1e300;
    for (int rep = 0; rep < repeat; ++rep) {
      const double t0 = now(), c0 = cpu_now();
      const m3c2::Result res = m3c2::compute(a, b, q, params, run);
      t_engine = std::min(t_engine, now() - t0), cpu_engine = std::min(cpu_engine, cpu_now() - c0);
      // FNV-1a over the bits of the columns a speed change must leave alone.
      hash = 1469598103934665603ull;
      const auto mix = [&](const void* data, std::size_t bytes) {
        for (std::size_t i = 0; i < bytes; ++i)
          hash = (hash ^ static_cast<const unsigned char*>(data)[i]) * 1099511628211ull;
      };
      for (const auto* v : {&res.distance, &res.lod, &res.sigma1, &res.sigma2, &res.normal, &res.roughness,
                            &res.normal_scale, &res.i1, &res.i2})
        mix(v->data(), v->size() * sizeof(double));
      mix(res.n1.data(), res.n1.size() * 4), mix(res.n2.data(), res.n2.size() * 4);
      mix(res.status.data(), res.status.size() * sizeof(res.status[0]));
    }
  }
  std::printf(
      "{\"core_points\": %zu, \"threads\": %d, \"build_s\": %.6f, \"normals_s\": %.6f, \"cylinders_s\": %.6f, "
      "\"total_s\": %.6f, \"cpu_build_s\": %.6f, \"cpu_normals_s\": %.6f, \"cpu_cylinders_s\": %.6f, "
      "\"cpu_total_s\": %.6f, \"engine_s\": %.6f, \"cpu_engine_s\": %.6f, \"engine_hash\": \"%016llx\", "
      "\"neighbours_mean\": %.2f, \"cylinder_points_mean\": %.2f, \"sink\": %.6g}\n",
      m, threads, t_build, t_normals, t_cylinders, t_build + t_normals + t_cylinders, cpu_build, cpu_normals,
      cpu_cylinders, cpu_build + cpu_normals + cpu_cylinders, t_engine, cpu_engine, (unsigned long long)hash,
      neighbours, in_cylinders, sink);
}
