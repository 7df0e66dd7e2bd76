// CylinderIndex: one cloud's index, queried with cylinders of any diameter and length through
// the very steps of compute() (project_full_depth, central_spread), so that a cylinder of the
// index's smallest diameter summarises as compute()'s does, bit for bit.

#include <m3c2/cylinder_index.hpp>
#include <m3c2/errors.hpp>

#include "index/spatial_order.hpp"
#include "pipeline/core_point.hpp"
#include "support/parallel_for.hpp"

#include <cmath>
#include <limits>
#include <string>

namespace m3c2 {

struct CylinderIndex::State {
  double smallest_diameter = 0.0;
  detail::Octree tree;
};

CylinderIndex::CylinderIndex(PointsView cloud, double smallest_diameter, const RunOptions& run) {
  detail::require_positive("the cylinder diameter", smallest_diameter);
  // compute()'s grid for this projection scale and no normal scales (core_point.hpp).
  const detail::OctreeGrid grid = detail::grid_for({}, smallest_diameter);
  state_ = std::make_unique<State>(State{
      smallest_diameter, detail::index_of(cloud, "cloud", grid, {.build_threads = detail::requested_threads(run)})});
}

CylinderIndex::~CylinderIndex() = default;
CylinderIndex::CylinderIndex(CylinderIndex&&) noexcept = default;
CylinderIndex& CylinderIndex::operator=(CylinderIndex&&) noexcept = default;

CylinderStatistics CylinderIndex::statistics(PointsView core_points, const std::vector<double>& normals,
                                             double diameter, double half_length, const RunOptions& run) const {
  const std::size_t n = core_points.size();
  if (normals.size() != 3 * n)
    throw InvalidArgument("normals must hold 3 values per core point (" + std::to_string(3 * n) + "), got " +
                          std::to_string(normals.size()));
  detail::require_positive("the cylinder half-length", half_length);
  if (!(diameter >= state_->smallest_diameter) || !std::isfinite(diameter))
    throw InvalidArgument("the cylinder diameter (" + std::to_string(diameter) +
                          ") must be finite and at least the index's smallest (" +
                          std::to_string(state_->smallest_diameter) + ")");
  detail::require_finite_points("core points", core_points);
  Params params;  // the default statistics: single pass, mean, sample variance
  params.projection_diameter = diameter;
  params.max_depth = half_length;
  CylinderStatistics out;
  out.count.assign(n, 0);
  out.mean.assign(n, std::numeric_limits<double>::quiet_NaN());
  out.sigma.assign(n, std::numeric_limits<double>::quiet_NaN());
  const std::vector<std::uint32_t> order = detail::morton_order(core_points);  // neighbours share descents
  detail::parallel_blocks<detail::Scratch>(n, run, [&](std::size_t begin, std::size_t end, detail::Scratch& s) {
    for (std::size_t k = begin; k < end; ++k) {
      const std::size_t i = order[k];
      const auto axis = detail::unit(Vec3(normals[3 * i], normals[3 * i + 1], normals[3 * i + 2]), 0.0);
      if (!axis) continue;
      detail::project_full_depth(state_->tree, core_points[i], *axis, params, s.projection, s.t1);
      if (s.t1.empty()) continue;
      const detail::CylinderSummary summary = detail::summarise(s.t1, params, s);
      out.count[i] = summary.n;
      out.mean[i] = summary.spread.centre;
      out.sigma[i] = summary.spread.sigma;
    }
  });
  return out;
}

}  // namespace m3c2
