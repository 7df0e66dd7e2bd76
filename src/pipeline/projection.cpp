#include "pipeline/projection.hpp"

#include "pipeline/statistics.hpp"

#include <algorithm>
#include <cmath>

namespace m3c2::detail {
namespace {

Cylinder make_cylinder(const Vec3& core, const Vec3& normal, const Params& params, double half_length) {
  return {core, normal, 0.5 * params.projection_diameter, params.positive_search_only ? 0.0 : -half_length,
          half_length};
}

/// Truncates `t` (offsets of the full cylinder) as CloudCompare's progressive search would.
/// `index` (if any) is truncated alike.
void progressive_truncate(std::vector<double>& t, const Params& params, ProjectionScratch& s,
                          std::vector<std::uint32_t>* index) {
  const double step = 0.5 * params.projection_diameter;
  s.full.swap(t);
  if (index) s.full_index.swap(*index);
  std::size_t previous = 0;
  for (double h = step;; h = std::min(h + step, params.max_depth)) {
    t.clear();
    if (index) index->clear();
    for (std::size_t k = 0; k < s.full.size(); ++k)
      if (std::abs(s.full[k]) <= h) {
        t.push_back(s.full[k]);
        if (index) index->push_back(s.full_index[k]);
      }
    if (h >= params.max_depth) return;
    if (t.size() == previous) continue;
    previous = t.size();
    if (t.size() < params.min_points) continue;
    const Spread sp = central_spread(t, params, s.work);
    if (std::abs(sp.centre) + 2.0 * sp.sigma < h) return;
  }
}

}  // namespace

void project_first_pass(const Octree& cloud, const Vec3& core, const Vec3& normal, const Params& params,
                        ProjectionScratch& s, std::vector<double>& t, std::vector<std::uint32_t>* index) {
  cloud.cylinder(make_cylinder(core, normal, params, params.first_pass_depth), t, &s.descent, index);
}

void project_full_depth(const Octree& cloud, const Vec3& core, const Vec3& normal, const Params& params,
                        ProjectionScratch& s, std::vector<double>& t, std::vector<std::uint32_t>* index) {
  cloud.cylinder(make_cylinder(core, normal, params, params.max_depth), t, &s.descent, index);
  if (params.depth_search == DepthSearch::kProgressive) progressive_truncate(t, params, s, index);
}

void project(const Octree& reference, const Octree& compared, const Vec3& core, const Vec3& normal,
             const Params& params, ProjectionScratch& s, std::vector<double>& t1, std::vector<double>& t2,
             std::vector<std::uint32_t>* index1, std::vector<std::uint32_t>* index2) {
  if (params.depth_search == DepthSearch::kTwoPass) {
    project_first_pass(reference, core, normal, params, s, t1, index1);
    project_first_pass(compared, core, normal, params, s, t2, index2);
    if (!t1.empty() && !t2.empty()) return;
  }
  project_full_depth(reference, core, normal, params, s, t1, index1);
  project_full_depth(compared, core, normal, params, s, t2, index2);
}

}  // namespace m3c2::detail
