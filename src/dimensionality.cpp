// Multi-scale dimensionality (Brodu & Lague 2012): the neighbourhood moments of every scale from
// one octree traversal (the sums normals use, octree.hpp), then the eigenvalues of each centred
// co-moment matrix with Eigen's iterative solver.

#include <m3c2/dimensionality.hpp>
#include <m3c2/errors.hpp>

#include "normals.hpp"
#include "octree.hpp"
#include "parallel_for.hpp"
#include "spatial_order.hpp"
#include "validation.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>

namespace m3c2 {
namespace {

/// Proportions (descending) of the eigenvalues of a centred co-moment sum (v - mean)(v - mean)^T.
/// The co-moment is about the neighbours' own mean (moments.hpp), so its entries carry no
/// coordinate offset whatever the distance to the origin. Scaled to unit largest entry before
/// the solve (the proportions do not depend on the scale). False where there is no variance.
bool eigen_proportions(const Eigen::Matrix3d& comoment, double* p) {
  const double scale = comoment.cwiseAbs().maxCoeff();
  if (!(scale > 0.0) || !std::isfinite(scale)) return false;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(comoment / scale, Eigen::EigenvaluesOnly);
  if (solver.info() != Eigen::Success) return false;
  const Eigen::Vector3d ascending = solver.eigenvalues().cwiseMax(0.0);  // rounding can leave -1e-17
  const double total = ascending.sum();
  if (!(total > 0.0)) return false;
  for (int j = 0; j < 3; ++j) p[j] = ascending(2 - j) / total;
  return true;
}

void barycentric_of(const double* p, double* abc) {
  abc[0] = p[0] - p[1];
  abc[1] = 2.0 * (p[1] - p[2]);
  abc[2] = 3.0 * p[2];
}

}  // namespace

DimensionalityResult dimensionality(PointsView cloud, PointsView core_points, const std::vector<double>& diameters,
                                    std::uint32_t min_points, const RunOptions& run) {
  if (diameters.empty()) throw InvalidArgument("dimensionality needs at least one scale (diameter)");
  for (const double d : diameters) detail::require_positive("dimensionality scale (diameter)", d);
  if (min_points < 3)
    throw InvalidArgument("min_points must be >= 3 for the eigenvalues of a neighbourhood, got " +
                          std::to_string(min_points));
  if (cloud.empty()) throw InvalidArgument("the cloud is empty");
  detail::require_finite_points("core points", core_points);
  // by_size[r]: the scale of rank r, ascending, as ball_moments wants its radii.
  const std::size_t scales = diameters.size();
  std::vector<std::size_t> by_size(scales);
  std::iota(by_size.begin(), by_size.end(), std::size_t(0));
  std::sort(by_size.begin(), by_size.end(), [&](auto a, auto b) { return diameters[a] < diameters[b]; });
  for (std::size_t r = 1; r < scales; ++r)
    if (diameters[by_size[r]] == diameters[by_size[r - 1]])
      throw InvalidArgument("dimensionality scales must be distinct, got " + std::to_string(diameters[by_size[r]]) +
                            " twice");
  std::vector<double> radii;
  for (const std::size_t k : by_size) radii.push_back(0.5 * diameters[k]);

  // Cells of about D_max / 8 (not D_min / 16 as for normals): a sphere's crossing leaves are then
  // mostly single cells, folded without keys; measured 1.6x faster than D_min / 16 on the bench's
  // 10 scales (bench/dimensionality_bench.cpp). Derived from the scales alone, as every tile's.
  const detail::OctreeGrid grid = detail::octree_grid(radii.back() * 4.0, radii.back() * 2.0);
  const detail::Octree tree = [&] {
    try {
      return detail::Octree(cloud, grid, true, "the cloud");
    } catch (const InvalidArgument&) {
      detail::require_finite_points("cloud", cloud);
      throw;
    }
  }();

  const std::size_t n = core_points.size();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  DimensionalityResult out;
  out.scales = scales;
  out.proportions.assign(n * scales * 3, nan);
  out.barycentric.assign(n * scales * 3, nan);
  out.count.assign(n * scales, 0);
  out.status.assign(n, PointStatus::kTooFewNormalPoints);
  const auto order = detail::morton_order(core_points);
  detail::parallel_blocks<detail::NormalScratch>(
      n, run, [&](std::size_t begin, std::size_t end, detail::NormalScratch& s) {
        for (std::size_t j = begin; j < end; ++j) {
          const std::size_t i = order[j];
          detail::moments_by_scale(tree, core_points[i], radii, s);
          // From the largest scale down: a scale without usable neighbours (too few, or coincident)
          // repeats the next larger scale's values, CANUPO's rule. Neighbourhoods are nested, so when
          // the largest scale is unusable every scale is: the point keeps NaN and says why.
          double p[3], abc[3];
          for (std::size_t r = scales; r-- > 0;) {
            const std::size_t k = by_size[r];
            const auto& m = s.moments[r];
            out.count[i * scales + k] = m.count;
            const bool usable = m.count >= min_points && eigen_proportions(m.comoment, p);
            if (r == scales - 1) {
              if (!usable) {
                out.status[i] =
                    m.count >= min_points ? PointStatus::kDegenerateNormal : PointStatus::kTooFewNormalPoints;
                for (std::size_t q = 0; q < r; ++q) out.count[i * scales + by_size[q]] = s.moments[q].count;
                break;
              }
              out.status[i] = PointStatus::kOk;
            }
            if (usable) barycentric_of(p, abc);
            std::copy(p, p + 3, &out.proportions[(i * scales + k) * 3]);
            std::copy(abc, abc + 3, &out.barycentric[(i * scales + k) * 3]);
          }
        }
      });
  return out;
}

}  // namespace m3c2
