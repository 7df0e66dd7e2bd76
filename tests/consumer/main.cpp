// Uses the installed m3c2 engine: two parallel horizontal planes 0.5 apart must give an M3C2
// distance of 0.5 (section 3.1: the distance between the two planes along the normal) at every
// core point, to 1e-9, with a finite level of detection. Exits non-zero otherwise.

#include <m3c2/m3c2.hpp>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

namespace {

std::vector<double> plane(double z) {
  std::vector<double> xyz;
  for (int i = -20; i <= 20; ++i)
    for (int j = -20; j <= 20; ++j) xyz.insert(xyz.end(), {0.1 * i, 0.1 * j, z});
  return xyz;
}

}  // namespace

int main() {
  const std::vector<double> ref = plane(0.0), cmp = plane(0.5);
  const std::vector<double> core = {0.0, 0.0, 0.0, 0.5, -0.3, 0.0, -1.0, 1.0, 0.0};
  m3c2::Params params;
  params.normal_diameters = {0.5};
  params.projection_diameter = 0.3;
  params.max_depth = 1.0;
  const m3c2::Result r =
      m3c2::compute({ref.data(), ref.size() / 3}, {cmp.data(), cmp.size() / 3}, {core.data(), core.size() / 3}, params);
  int failures = 0;
  for (std::size_t i = 0; i < r.size(); ++i) {
    const bool ok =
        r.status[i] == m3c2::PointStatus::kOk && std::abs(r.distance[i] - 0.5) <= 1e-9 && std::isfinite(r.lod[i]);
    const std::string status(m3c2::status_name(r.status[i]));
    std::printf("core point %zu: distance %.12f, lod %.6f, status %s%s\n", i, r.distance[i], r.lod[i], status.c_str(),
                ok ? "" : "  <- expected 0.5 to 1e-9, status ok");
    failures += !ok;
  }
  if (r.size() != 3) failures = 1;
  std::printf("%s\n", failures ? "consumer: FAILED" : "consumer: distance 0.5 between the planes, as expected");
  return failures ? 1 : 0;
}
