// Prints every bit of the engine's results on a fixed synthetic scene, one line per run
// configuration and result field (hexadecimal IEEE bits), for scripts/check-serial.sh: two
// builds (OpenMP and serial, builtins and portable fallbacks, GCC and Clang) must print the same.
// The scene comes from SplitMix64 draws turned into doubles by hand, so that no
// library-defined distribution (std::normal_distribution's algorithm is unspecified) enters.
// Usage: m3c2_dump [THREADS]   (0, the default, = all)

#include <m3c2/m3c2.hpp>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace {

struct Draws {
  std::uint64_t state;
  std::uint64_t next() {
    std::uint64_t z = (state += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
  }
  double uniform() { return double(next() >> 11) * 0x1.0p-53; }  // [0, 1)
};

/// A rough surface z = f(x, y) + noise with a step of `shift` in one half, n x n points.
std::vector<double> surface(std::uint64_t seed, int n, double shift) {
  Draws d{seed};
  std::vector<double> xyz;
  for (int i = 0; i < n * n; ++i) {
    const double x = 10.0 * d.uniform(), y = 10.0 * d.uniform();
    double z = 0.3 * (x - 5.0) * (x - 5.0) / 25.0 + 0.05 * (d.uniform() - 0.5) + (x + y > 10.0 ? 0.2 : 0.0);
    if (y > 7.0) z = 0.4 * d.uniform();  // a rougher patch
    xyz.insert(xyz.end(), {x + 1000.25, y - 2000.5, z + shift});
  }
  return xyz;
}

std::uint64_t bits(double v) {
  std::uint64_t b;
  std::memcpy(&b, &v, sizeof b);
  return b;
}

void line(const std::string& run, const char* field, const std::vector<double>& v) {
  std::printf("%s %s", run.c_str(), field);
  for (const double x : v) std::printf(" %016llx", static_cast<unsigned long long>(bits(x)));
  std::printf("\n");
}

template <class T>
void line_int(const std::string& run, const char* field, const std::vector<T>& v) {
  std::printf("%s %s", run.c_str(), field);
  for (const T x : v) std::printf(" %llu", static_cast<unsigned long long>(x));
  std::printf("\n");
}

void dump(const std::string& run, const m3c2::Result& r) {
  line(run, "distance", r.distance);
  line(run, "lod", r.lod);
  line_int(run, "significant", r.significant);
  line_int(run, "n1", r.n1);
  line_int(run, "n2", r.n2);
  line(run, "sigma1", r.sigma1);
  line(run, "sigma2", r.sigma2);
  line(run, "i1", r.i1);
  line(run, "i2", r.i2);
  line(run, "normal", r.normal);
  line(run, "normal_scale", r.normal_scale);
  line(run, "roughness", r.roughness);
  std::vector<int> status;
  for (const m3c2::PointStatus st : r.status) status.push_back(int(st));
  line_int(run, "status", status);
}

}  // namespace

int main(int argc, char** argv) {
  m3c2::RunOptions run;
  run.threads = argc > 1 ? std::atoi(argv[1]) : 0;
  const std::vector<double> ref = surface(1, 150, 0.0), cmp = surface(2, 140, 0.1);
  const m3c2::PointsView reference(ref.data(), ref.size() / 3), compared(cmp.data(), cmp.size() / 3);
  const std::vector<std::uint64_t> keep = m3c2::subsample_min_spacing(reference, 0.25);
  std::vector<double> core;
  for (const std::uint64_t i : keep) core.insert(core.end(), {ref[3 * i], ref[3 * i + 1], ref[3 * i + 2]});
  const m3c2::PointsView cores(core.data(), core.size() / 3);
  line_int("subsample", "index", keep);

  m3c2::Params base;
  base.normal_diameters = {0.5, 1.0, 2.0};
  base.projection_diameter = 0.6;
  base.max_depth = 1.5;
  dump("multiscale", m3c2::compute(reference, compared, cores, base, run));

  m3c2::Params p = base;
  p.statistic = m3c2::Statistic::kMedian;
  p.lod = m3c2::Lod::kAuto;
  p.normal_source = m3c2::NormalSource::kMean;
  p.depth_search = m3c2::DepthSearch::kProgressive;
  dump("median-mean-progressive", m3c2::compute(reference, compared, cores, p, run));

  p = base;
  p.normal_diameters = {1.0};
  p.lod = m3c2::Lod::kBootstrap;
  p.bootstrap_samples = 40;
  p.bootstrap_seed = 12345;
  p.registration_error = 0.01;
  p.depth_search = m3c2::DepthSearch::kTwoPass;
  p.first_pass_depth = 0.3;
  p.scale_selection = m3c2::ScaleSelection::kCloudCompare;
  dump("bootstrap-twopass", m3c2::compute(reference, compared, cores, p, run));

  const m3c2::NormalsResult nr = m3c2::compute_normals(reference, cores, base, run);
  line("normals", "normal", nr.normal);
  line("normals", "roughness", nr.roughness);
  line("roughness", "sigma",
       m3c2::roughness_by_scale(reference, cores, {0.5, 1.0, 2.0}, m3c2::Variance::kSample, 4, run));

  m3c2::C2CParams c;
  c.model = m3c2::LocalModel::kPlane;
  const m3c2::C2CResult cr = m3c2::c2c(reference, compared, c, run);
  line("c2c", "distance", cr.distance);
  line("c2c", "hf_distance", cr.hf_distance);
  line_int("c2c", "nearest", cr.nearest);

  const m3c2::Grid g = m3c2::grid_core_points(reference, 0.5);
  line("grid", "core_points", g.core_points);
  return 0;
}
