// roughness_by_scale(): the roughness sigma(D) of section 5.1 (Fig. 6a) at each of several
// scales, from one index with node moments and the sums and plane fits of the normals
// (pipeline/normals.hpp, section 3.1.2).

#include <m3c2/m3c2.hpp>

#include "index/spatial_order.hpp"
#include "pipeline/core_point.hpp"
#include "pipeline/plane_fit.hpp"
#include "support/parallel_for.hpp"
#include "support/thread_limits.hpp"

#include <algorithm>
#include <cstddef>
#include <limits>
#include <string>
#include <vector>

namespace m3c2 {

using detail::grid_for;
using detail::index_of;
using detail::Octree;

std::vector<double> roughness_by_scale(PointsView cloud, PointsView core_points, const std::vector<double>& diameters,
                                       Variance variance, std::uint32_t min_points, const RunOptions& run) {
  Params check;
  check.normal_diameters = diameters;
  detail::validate_normal_params(check);
  if (min_points < 3)
    throw InvalidArgument("min_points must be >= 3 for a plane fit, got " + std::to_string(min_points));
  detail::require_finite_points("core points", core_points);
  std::vector<std::size_t> by_size(diameters.size());
  for (std::size_t k = 0; k < by_size.size(); ++k) by_size[k] = k;
  std::sort(by_size.begin(), by_size.end(), [&](auto a, auto b) { return diameters[a] < diameters[b]; });
  std::vector<double> radii;
  for (const std::size_t k : by_size) radii.push_back(0.5 * diameters[k]);

  const Octree tree = index_of(cloud, "cloud", grid_for(diameters, 0.0),
                               {.node_moments = true, .build_threads = detail::requested_threads(run)});
  const std::size_t scales = diameters.size();
  std::vector<double> out(core_points.size() * scales, std::numeric_limits<double>::quiet_NaN());
  const auto order = detail::morton_order(core_points);
  detail::parallel_blocks<detail::NormalScratch>(
      core_points.size(), run, [&](std::size_t begin, std::size_t end, detail::NormalScratch& s) {
        for (std::size_t j = begin; j < end; ++j) {
          const std::size_t i = order[j];
          detail::moments_by_scale(tree, core_points[i], radii, s);
          bool gathered = false;  // the largest sphere's offsets, for the centred pass
          std::vector<double> kept;
          for (std::size_t k = 0; k < scales; ++k) {
            const auto& m = s.moments[k];
            if (m.count < min_points) continue;
            const detail::PlaneFit fit = detail::fit_plane(m.comoment);
            double sigma = detail::plane_roughness(fit.eigenvalues(0), m.count, variance);
            if (detail::roughness_needs_centred_pass(fit.eigenvalues) && fit.normal.allFinite()) {
              if (!gathered) {
                s.offsets.clear();
                tree.ball_offsets(core_points[i], radii.back(), s.offsets, s.octree);
                gathered = true;
              }
              // This scale's points: the test of squared_distance() on the same differences.
              const double r2 = radii[k] * radii[k];
              kept.clear();
              for (std::size_t j = 0; j + 2 < s.offsets.size(); j += 3) {
                const double dx = s.offsets[j], dy = s.offsets[j + 1], dz = s.offsets[j + 2];
                if (dx * dx + dy * dy + dz * dz <= r2) kept.insert(kept.end(), {dx, dy, dz});
              }
              sigma = detail::centred_roughness(kept, fit.normal, variance);
            }
            out[i * scales + by_size[k]] = sigma;
          }
        }
      });
  return out;
}

}  // namespace m3c2
