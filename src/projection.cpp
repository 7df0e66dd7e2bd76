#include "projection.hpp"

#include "statistics.hpp"

#include <algorithm>
#include <cmath>

namespace m3c2::detail {
namespace {

Cylinder make_cylinder(const Vec3& core, const Vec3& normal, const Params& params, double half_length) {
  return {core, normal, 0.5 * params.projection_diameter, params.positive_search_only ? 0.0 : -half_length,
          half_length};
}

/// Truncates `t` (offsets of the full cylinder) as CloudCompare's progressive search would.
void progressive_truncate(std::vector<double>& t, const Params& params, ProjectionScratch& s) {
  const double step = 0.5 * params.projection_diameter;
  s.full.swap(t);
  std::size_t previous = 0;
  for (double h = step;; h = std::min(h + step, params.max_depth)) {
    t.clear();
    for (const double v : s.full)
      if (std::abs(v) <= h) t.push_back(v);
    if (h >= params.max_depth) return;
    if (t.size() == previous) continue;
    previous = t.size();
    if (t.size() < params.min_points) continue;
    const Spread sp = central_spread(t, params, s.work);
    if (std::abs(sp.centre) + 2.0 * sp.sigma < h) return;
  }
}

}  // namespace

void project(const Octree& reference, const Octree& compared, const Vec3& core, const Vec3& normal,
             const Params& params, ProjectionScratch& s, std::vector<double>& t1, std::vector<double>& t2) {
  if (params.depth_search == DepthSearch::kTwoPass) {
    const Cylinder short_cyl = make_cylinder(core, normal, params, params.first_pass_depth);
    reference.cylinder(short_cyl, t1, &s.descent);
    compared.cylinder(short_cyl, t2, &s.descent);
    if (!t1.empty() && !t2.empty()) return;
  }
  const Cylinder cyl = make_cylinder(core, normal, params, params.max_depth);
  reference.cylinder(cyl, t1, &s.descent);
  compared.cylinder(cyl, t2, &s.descent);
  if (params.depth_search == DepthSearch::kProgressive) {
    progressive_truncate(t1, params, s);
    progressive_truncate(t2, params, s);
  }
}

}  // namespace m3c2::detail
