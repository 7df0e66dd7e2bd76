#include "registration/pairing.hpp"

#include <m3c2/m3c2.hpp>

#include "index/distance.hpp"
#include "support/parallel_for.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace m3c2::detail {
namespace {

// Fixed blocks of sources: the partial sums of a block do not depend on which thread ran it.
constexpr std::size_t kBlock = 4096;

}  // namespace

Targets::Targets(PointsView reference, double normal_diameter, const RunOptions& run) {
  // The engine's normals (one scale, section 3.1.2); their orientation does not matter here: a
  // point-to-plane residual only changes sign with it.
  Params params;
  params.normal_diameters = {normal_diameter};
  const std::vector<double> all = compute_normals(reference, reference, params, run).normal;
  for (std::size_t i = 0; i < reference.size(); ++i) {
    if (!std::isfinite(all[3 * i])) continue;
    for (int a = 0; a < 3; ++a) xyz_.push_back(reference.coord(i, a)), normals_.push_back(all[3 * i + a]);
  }
  tree_ = std::make_unique<KdTree>(PointsView(xyz_.data(), size()));
}

std::uint32_t Targets::nearest(const Vec3& q, double max_distance) const { return tree_->nearest(q, max_distance); }

void pair_sources(const Targets& targets, const Sources& sources, const Pose& pose, double max_distance, Pairing& out,
                  const RunOptions& run) {
  out.target.assign(sources.count, Targets::kNone);
  out.residual.assign(sources.count, std::numeric_limits<double>::quiet_NaN());
  parallel_blocks<int>(
      sources.count, run,
      [&](std::size_t begin, std::size_t end, int&) {
        for (std::size_t j = begin; j < end; ++j) {
          const Vec3 q = pose.apply(sources[j]);
          const std::uint32_t t = targets.nearest(q, max_distance);
          if (t == Targets::kNone) continue;
          out.target[j] = t;
          out.residual[j] = targets.normal(t).dot(q - targets.point(t));
        }
      },
      kBlock);
}

NormalEquations normal_equations(const Targets& targets, const Sources& sources, const Pose& pose,
                                 const Pairing& pairing, double low, double high, const RunOptions& run) {
  const std::size_t blocks = (sources.count + kBlock - 1) / kBlock;
  std::vector<NormalEquations> partial(blocks);
  parallel_blocks<int>(
      sources.count, run,
      [&](std::size_t begin, std::size_t end, int&) {
        NormalEquations& sum = partial[begin / kBlock];
        for (std::size_t j = begin; j < end; ++j) {
          const double r = pairing.residual[j];
          if (!(r >= low && r <= high)) continue;  // unpaired (NaN) or rejected
          const Vec3 q = pose.apply(sources[j]);
          const Vec3 n = targets.normal(pairing.target[j]);
          Vector6d row;
          const Vec3 arm = q - pose.centre;
          row << arm.cross(n), n;
          sum.jtj.selfadjointView<Eigen::Upper>().rankUpdate(row);
          sum.jtr += r * row;
          sum.sum_squares += r * r;
          ++sum.pairs;
        }
      },
      kBlock);
  NormalEquations total;
  for (const NormalEquations& p : partial) {
    total.jtj += p.jtj;
    total.jtr += p.jtr;
    total.sum_squares += p.sum_squares;
    total.pairs += p.pairs;
  }
  total.jtj.triangularView<Eigen::StrictlyLower>() = total.jtj.transpose();
  return total;
}

}  // namespace m3c2::detail
