// Multi-scale dimensionality (Brodu & Lague 2012): the neighbours of the largest scale gathered
// once (their offsets from the core point and squared distances, in the octree's key order, from
// the slot runs of Octree::ball_runs), each assigned to the shell between two consecutive scales
// (ShellIndex, a table lookup) and summed into it in one pass (sums shifted by the shell's first
// point); then the balls as the union of their shells (merge_into, innermost first); the
// eigenvalues of each centred co-moment matrix (Eigen's closed form, its iterative solver near
// double roots).
//
// Why shells and not the octree's node moments (octree.hpp, as normals use): every point of the
// cloud is a core point here, at 10 scales of up to several hundred neighbours, and folding the
// nodes crossing each of the 10 spheres cost more than touching each neighbour of the largest
// sphere once (with the closed-form eigenvalues, measured ~2.2x less CPU on
// bench/dimensionality_bench.cpp, docs/performance.md).
// The sums are a function of the neighbour set and its key order (the order of the points' grid
// cells, ties by input order), so every thread count and every tile gives the same bits.

#include <m3c2/dimensionality.hpp>
#include <m3c2/errors.hpp>

#include "features/shell_index.hpp"
#include "index/moments.hpp"
#include "index/octree.hpp"
#include "index/spatial_order.hpp"
#include "pipeline/validation.hpp"
#include "support/parallel_for.hpp"
#include "support/thread_limits.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>

namespace m3c2 {
namespace {

/// Octree cells of about D_max / 8: measured on bench/dimensionality_bench.cpp as fast as D_max / 4
/// and 15 % faster than D_max / 16 (fewer nodes against fewer points tested outside the sphere).
constexpr double kCellDivisor = 8.0;

/// Proportions (descending) of the eigenvalues of a centred co-moment sum (v - mean)(v - mean)^T.
/// The co-moment is about the neighbours' own mean (moments.hpp), so its entries carry no
/// coordinate offset whatever the distance to the origin. Scaled to unit largest entry before
/// the solve (the proportions do not depend on the scale). False where there is no variance.
///
/// Eigen's closed form (computeDirect, the roots of the characteristic cubic) is 4x cheaper than
/// its iterative solver, and accurate to ~1e-15 of the largest eigenvalue when the eigenvalues
/// are apart; near a double root its error grows to ~sqrt(eps) (8e-9 on a line of points). So
/// where two roots lie within kCloseRoots of the largest, the iterative solver is run instead.
bool eigen_proportions(const Eigen::Matrix3d& comoment, double* p) {
  constexpr double kCloseRoots = 1e-3;
  const double scale = comoment.cwiseAbs().maxCoeff();
  if (!(scale > 0.0) || !std::isfinite(scale)) return false;
  const Eigen::Matrix3d scaled = comoment / scale;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver;
  solver.computeDirect(scaled, Eigen::EigenvaluesOnly);
  Eigen::Vector3d e = solver.eigenvalues();  // ascending
  if (!e.allFinite() || e(1) - e(0) < kCloseRoots * std::abs(e(2)) || e(2) - e(1) < kCloseRoots * std::abs(e(2))) {
    solver.compute(scaled, Eigen::EigenvaluesOnly);
    if (solver.info() != Eigen::Success) return false;
    e = solver.eigenvalues();
  }
  const Eigen::Vector3d ascending = e.cwiseMax(0.0);  // rounding can leave -1e-17
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

/// One shell's running sums, together in memory: each neighbour updates one of them.
struct ShellSums {
  double pivot[3];  // its first point's offset
  double sum[3];    // of w = offset - pivot
  double c[6];      // of w w^T (xx, xy, xz, yy, yz, zz)
  std::uint32_t count;
};

struct ShellScratch {
  detail::DescentCache descent;
  std::vector<std::array<std::uint32_t, 2>> runs;  // the largest sphere's candidates (Octree::ball_runs)
  std::vector<double> near;            // 4 per neighbour of the largest sphere: p - core, its squared length
  std::vector<ShellSums> shells;       // per scale rank
  std::vector<detail::Moments> balls;  // per scale rank: the moments of its ball
};

/// Writes to s.near the offset p - core and its squared length (as detail::squared_distance
/// computes it) of each point p within `radius` of `core`, in key order; returns their number.
/// s.near only grows: the slots it has are written, never zeroed first.
std::size_t gather_ball(const detail::Octree& tree, const Vec3& core, double radius, ShellScratch& s) {
  s.runs.clear();
  tree.ball_runs(core, radius, s.runs, &s.descent);
  std::size_t candidates = 0;
  for (const auto& [begin, end] : s.runs) candidates += end - begin;
  if (s.near.size() < 4 * candidates) s.near.resize(4 * candidates);
  const double r2 = radius * radius;
  double* out = s.near.data();
  std::size_t kept = 0;
  for (const auto& [begin, end] : s.runs) {
    const double* p = tree.slot_xyz(begin);
    // About half a crossing leaf's points are kept, at random: each is written and the end
    // advanced by its test, without a branch.
    for (std::uint32_t slot = begin; slot < end; ++slot, p += 3) {
      const double dx = p[0] - core.x(), dy = p[1] - core.y(), dz = p[2] - core.z();
      const double d2 = dx * dx + dy * dy + dz * dz;
      double* o = out + 4 * kept;
      o[0] = dx, o[1] = dy, o[2] = dz, o[3] = d2;
      kept += d2 <= r2;
    }
  }
  return kept;
}

/// The moments of the balls of radius sqrt(r2[r]) (ascending) about the core point from the
/// first m entries of s.near (gather_ball at the largest radius): a neighbour is within ball r
/// iff its squared distance is <= r2[r].
void ball_moments_by_shell(const std::vector<double>& r2, const detail::ShellIndex& shell_of, std::size_t m,
                           ShellScratch& s) {
  const std::size_t scales = r2.size();
  const double* v = s.near.data();
  s.shells.assign(scales, ShellSums{});
  // One pass in key order: each neighbour's shell, and the shell's sums of w and w w^T, w the
  // offset from the shell's first point (its pivot). The shifted sums give the co-moment about
  // the shell's mean, C = S_ww - S_w S_w^T / n, with a rounding error ~eps n max|w|^2: a pivot
  // inside the shell keeps it of the order of the shell's own spread (a pivot far from a tight
  // cluster would not), far below the 1e-9 of the brute-force check.
  for (std::size_t j = 0; j < m; ++j) {
    const double dx = v[4 * j], dy = v[4 * j + 1], dz = v[4 * j + 2], d2 = v[4 * j + 3];
    const std::size_t r = shell_of(d2);  // the smallest scale holding j
    ShellSums& sh = s.shells[r];
    if (sh.count++ == 0) sh.pivot[0] = dx, sh.pivot[1] = dy, sh.pivot[2] = dz;
    const double x = dx - sh.pivot[0], y = dy - sh.pivot[1], z = dz - sh.pivot[2];
    sh.sum[0] += x, sh.sum[1] += y, sh.sum[2] += z;
    double* c = sh.c;
    c[0] += x * x, c[1] += x * y, c[2] += x * z, c[3] += y * y, c[4] += y * z, c[5] += z * z;
  }
  // The balls: the union of their shells, innermost first (Chan et al.'s exact merge).
  s.balls.resize(scales);
  detail::Moments acc;
  for (std::size_t r = 0; r < scales; ++r) {
    detail::Moments shell;
    const ShellSums& sh = s.shells[r];
    if (sh.count > 0) {
      const double n = double(sh.count);
      const double *sum = sh.sum, *c = sh.c;
      const double mx = sum[0] / n, my = sum[1] / n, mz = sum[2] / n;
      shell.count = n;
      shell.mean = Vec3(sh.pivot[0] + mx, sh.pivot[1] + my, sh.pivot[2] + mz);
      shell.comoment = {c[0] - sum[0] * mx, c[1] - sum[0] * my, c[2] - sum[0] * mz,
                        c[3] - sum[1] * my, c[4] - sum[1] * mz, c[5] - sum[2] * mz};
    }
    detail::merge_into(acc, shell);
    s.balls[r] = acc;
  }
}

Eigen::Matrix3d comoment_matrix(const detail::Moments& m) {
  const auto& c = m.comoment;
  Eigen::Matrix3d out;
  out << c[0], c[1], c[2], c[1], c[3], c[4], c[2], c[4], c[5];
  return out;
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

  if (scales > 255) throw InvalidArgument("dimensionality takes at most 255 scales, got " + std::to_string(scales));
  std::vector<double> r2;
  for (const double r : radii) r2.push_back(r * r);

  // Only the largest sphere is searched, with no node moments; cells of about D_max / kCellDivisor
  // (octree_grid takes D / 16). Derived from the scales alone, as every tile's.
  const detail::OctreeGrid grid = detail::octree_grid(radii.back() * 2.0 * 16.0 / kCellDivisor, 0.0);
  const detail::Octree tree = [&] {
    try {
      return detail::Octree(cloud, grid, {.cloud_name = "the cloud", .build_threads = detail::requested_threads(run)});
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
  const detail::ShellIndex shell_of(r2);
  const auto order = detail::morton_order(core_points);
  detail::parallel_blocks<ShellScratch>(n, run, [&](std::size_t begin, std::size_t end, ShellScratch& s) {
    for (std::size_t j = begin; j < end; ++j) {
      const std::size_t i = order[j];
      const std::size_t m = gather_ball(tree, core_points[i], radii.back(), s);
      ball_moments_by_shell(r2, shell_of, m, s);
      // From the largest scale down: a scale without usable neighbours (too few, or coincident)
      // repeats the next larger scale's values, CANUPO's rule. Neighbourhoods are nested, so when
      // the largest scale is unusable every scale is: the point keeps NaN and says why.
      double p[3], abc[3];
      for (std::size_t r = scales; r-- > 0;) {
        const std::size_t k = by_size[r];
        const detail::Moments& m = s.balls[r];
        const auto count = static_cast<std::uint32_t>(m.count);
        out.count[i * scales + k] = count;
        const bool usable = count >= min_points && eigen_proportions(comoment_matrix(m), p);
        if (r == scales - 1) {
          if (!usable) {
            out.status[i] = count >= min_points ? PointStatus::kDegenerateNormal : PointStatus::kTooFewNormalPoints;
            for (std::size_t q = 0; q < r; ++q)
              out.count[i * scales + by_size[q]] = static_cast<std::uint32_t>(s.balls[q].count);
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
