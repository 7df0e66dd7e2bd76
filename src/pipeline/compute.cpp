// compute() and compute_normals(): the per-core-point pipeline of section 3.1 (normal, then
// projection), the confidence of 3.3 / Appendix B and the statuses.

#include <m3c2/m3c2.hpp>

#include "index/spatial_order.hpp"
#include "pipeline/core_point.hpp"
#include "support/parallel_for.hpp"
#include "support/thread_limits.hpp"
#include "uncertainty/uncertainty.hpp"

#include <algorithm>
#include <cmath>
#include <exception>
#include <functional>
#include <memory>
#include <optional>

namespace m3c2 {
namespace {

using detail::grid_for;
using detail::index_of;
using detail::moments_needed;
using detail::NormalCloud;
using detail::NormalEstimate;
using detail::Octree;
using detail::OctreeGrid;
using detail::OrientedNormal;
using detail::Scratch;

/// Which clouds' indexes order their arrays in place (RunOptions::order_clouds_in_place) and
/// whether the core points are then the reordered reference itself, run in its slot order.
struct InPlace {
  bool reference = false, compared = false;
  bool core_in_slots = false;
};

/// Whether two point arrays share any memory.
bool overlap(PointsView a, PointsView b) {
  if (a.empty() || b.empty()) return false;
  const auto lo = [](PointsView v) { return reinterpret_cast<std::uintptr_t>(v.data()); };
  const auto hi = [&](PointsView v) { return lo(v) + 3 * sizeof(double) * v.size(); };
  return lo(a) < hi(b) && lo(b) < hi(a);
}

/// A cloud is ordered in place only where the parameters allow it (may_order_in_place) and it
/// shares no memory with the other cloud, nor with core points other than the whole reference
/// (the default core points, which are then run in slot order).
InPlace in_place_clouds(PointsView reference, PointsView compared, PointsView core_points, const Params& params,
                        const RunOptions& run) {
  InPlace p;
  if (!run.order_clouds_in_place || !detail::may_order_in_place(params) || overlap(reference, compared)) return p;
  const bool core_is_reference = core_points.data() == reference.data() && core_points.size() == reference.size();
  p.reference = core_is_reference || !overlap(core_points, reference);
  p.compared = !overlap(core_points, compared);
  p.core_in_slots = p.reference && core_is_reference;
  return p;
}

/// Both clouds' indexes and the core points' processing order (morton_order). With two threads
/// and two indexes of similar cost, each index is built on a thread of its own (the compared
/// one with the order): they are independent, and each is computed the same way whatever the
/// thread. The second thread is one of the OpenMP team that then runs the core points: a thread
/// of its own would compete with the team's idle threads, which spin for a while after each
/// parallel loop (W1: 11.6 against 7.9 ms in repeated runs). Otherwise (one cloud far larger,
/// as the one-cloud runs of the data-quality diagnosis, or more than two threads) the indexes
/// are built one after the other, each on all the threads (Octree's parallel build, whose
/// serial parts, the sort's first pass and the node split, leave a thread idle, which two
/// builds side by side do not).
/// Side by side, both indexes are built without their node moments, which are then summed on
/// both threads (Octree::add_moments, the same bits): the moments made the reference's index
/// about 1.5 times the compared one's, and the thread done first waited (S20: ~0.03 of 0.26 s).
/// `alongside` (the caller's own set-up) runs after the index of the thread expected to finish
/// first (the order costs about half an index).
std::pair<Octree, Octree> build_indexes(PointsView reference, PointsView compared, PointsView core_points,
                                        const Params& params, OctreeGrid grid, const RunOptions& run,
                                        const InPlace& in_place, std::vector<std::uint32_t>& core_order,
                                        const std::function<void()>& alongside) {
  const bool ref_moments = moments_needed(params, true), cmp_moments = moments_needed(params, false);
  // Core points in the reference's slot order need no order of their own (and are being moved).
  const auto order_core = [&] {
    if (!in_place.core_in_slots) core_order = detail::morton_order(core_points);
  };
  const int threads = detail::requested_threads(run);
  const double work0 = double(reference.size()) * 2, work1 = double(compared.size()) * 2 + double(core_points.size());
  // Side by side while the lighter part takes at least half the heavier's time (a judgement, not
  // a measured optimum: the diagnosis's one-cloud runs are far below it, a survey pair far above).
  constexpr double kSideBySide = 0.5;
  const bool side_by_side = threads == 2 && std::min(work0, work1) >= kSideBySide * std::max(work0, work1);
  detail::OpenMpTeam team(side_by_side ? 2 : 1);
  if (team.size() < 2) {
    order_core();
    if (alongside) alongside();
    Octree first =
        index_of(reference, "reference cloud", grid,
                 {.node_moments = ref_moments, .order_cloud_in_place = in_place.reference, .build_threads = threads});
    return {
        std::move(first),
        index_of(compared, "compared cloud", grid,
                 {.node_moments = cmp_moments, .order_cloud_in_place = in_place.compared, .build_threads = threads})};
  }
  std::optional<Octree> first, second;
  std::exception_ptr failure[2];
  const int lighter = work1 < work0 ? 1 : 0;
#if defined(_OPENMP)
#pragma omp parallel num_threads(2)
#endif
  {
    const int part = detail::thread_num();
    if (part == 0) team.started();
    const bool alone = detail::team_size() < 2;
    try {
      if (part == 0)
        first.emplace(index_of(reference, "reference cloud", grid, {.order_cloud_in_place = in_place.reference}));
      if (part == 1 || alone) {
        second.emplace(index_of(compared, "compared cloud", grid, {.order_cloud_in_place = in_place.compared}));
        order_core();
      }
      if ((part == lighter || alone) && alongside) alongside();
    } catch (...) {
      failure[part] = std::current_exception();
    }
  }
  for (const auto& f : failure)  // the reference's error first, as in a serial build
    if (f) std::rethrow_exception(f);
  if (ref_moments) first->add_moments(threads);
  if (cmp_moments) second->add_moments(threads);
  return {std::move(*first), std::move(*second)};
}

class Pipeline {
 public:
  /// `alongside`: the caller's set-up, run while the indexes are built (build_indexes).
  Pipeline(PointsView reference, PointsView compared, PointsView core_points, const Params& params,
           const std::vector<double>& core_normals, const RunOptions& run, const InPlace& in_place,
           const std::function<void()>& alongside, const detail::UncertaintyModel* uncertainty = nullptr)
      : params_(params),
        uncertainty_(uncertainty),
        core_normals_(core_normals),
        grid_(grid_for(params.normal_diameters, params.projection_diameter)),
        trees_(build_indexes(reference, compared, core_points, params, grid_, run, in_place, core_order_, alongside)),
        reference_tree_(trees_.first),
        compared_tree_(trees_.second),
        z_(detail::z_critical(params.confidence)) {
    const NormalSource src = params.normal_source;
    if (src == NormalSource::kReference || src == NormalSource::kMean || src == NormalSource::kHorizontal)
      reference_normals_.emplace(reference, reference_tree_, params, grid_);
    if (src == NormalSource::kCompared || src == NormalSource::kMean)
      compared_normals_.emplace(compared, compared_tree_, params, grid_);
  }

  /// The order in which to process the core points (Morton order); empty when they are the
  /// reference ordered in place, processed in its slot order (reference_tree()).
  const std::vector<std::uint32_t>& core_order() const { return core_order_; }
  const Octree& reference_tree() const { return reference_tree_; }

  void run(const Vec3& core, std::size_t i, Result& r, Scratch& s, detail::Pulse& pulse) const {
    const OrientedNormal n =
        detail::normal_at(core, i, params_, reference_normals_ ? &*reference_normals_ : nullptr,
                          compared_normals_ ? &*compared_normals_ : nullptr, core_normals_, s.normal);
    if (!detail::write_normal(n, i, r)) return;
    detail::project(reference_tree_, compared_tree_, core, n.normal, params_, s.projection, s.t1, s.t2,
                    uncertainty_ ? &s.index1 : nullptr, uncertainty_ ? &s.index2 : nullptr);
    detail::measure(params_, z_, uncertainty_ != nullptr, s, i, r, pulse);
    if (uncertainty_ && r.n1[i] > 0 && r.n2[i] > 0) uncertainty_->measure(core, n.normal, s.index1, s.index2, i, r);
  }

 private:
  const Params& params_;
  const detail::UncertaintyModel* uncertainty_;
  const std::vector<double>& core_normals_;
  OctreeGrid grid_;
  std::vector<std::uint32_t> core_order_;  // before trees_: build_indexes() fills it
  std::pair<Octree, Octree> trees_;
  const Octree &reference_tree_, &compared_tree_;
  std::optional<NormalCloud> reference_normals_, compared_normals_;
  double z_;
};

}  // namespace

Result compute(PointsView reference, PointsView compared, PointsView core_points, const Params& params,
               const RunOptions& run, const std::vector<double>& core_normals, const UncertaintyInputs& uncertainty) {
  detail::validate_params(params);
  detail::validate_uncertainty_params(params);
  if (reference.empty()) throw InvalidArgument("the reference cloud is empty");
  if (compared.empty()) throw InvalidArgument("the compared cloud is empty");
  // The clouds' coordinates are checked by their indexes, on the thread building each
  // (index_of); the core points here.
  // The clouds' coordinates are checked by their indexes; the core points here, unless they are
  // the reference itself (the default), whose index names its own non-finite coordinates.
  const bool cloud_itself = core_points.size() == reference.size() && core_points.data() == reference.data();
  if (!cloud_itself) detail::require_finite_points("core points", core_points);
  if (params.normal_source == NormalSource::kCorePoints && core_normals.size() != 3 * core_points.size())
    throw InvalidArgument("core_normals must hold 3 values per core point (" + std::to_string(3 * core_points.size()) +
                          "), got " + std::to_string(core_normals.size()));

  // Per-point uncertainty (PM, EP): its inputs checked, EP's compared cloud transformed.
  std::optional<detail::UncertaintyModel> model;
  if (params.uncertainty != Uncertainty::kEq1) model.emplace(params, uncertainty, reference, compared, run);
  Result result;  // its NaN-filled arrays are set up while the indexes are built
  const auto set_up = [&] {
    result.resize(core_points.size());
    if (!model) return;
    result.spread1.assign(core_points.size(), std::numeric_limits<double>::quiet_NaN());
    result.spread2.assign(core_points.size(), std::numeric_limits<double>::quiet_NaN());
    if (uncertainty.covariances && params.uncertainty == Uncertainty::kErrorPropagation) {
      result.covariance1.assign(9 * core_points.size(), std::numeric_limits<double>::quiet_NaN());
      result.covariance2.assign(9 * core_points.size(), std::numeric_limits<double>::quiet_NaN());
    }
  };
  const InPlace in_place = in_place_clouds(reference, compared, core_points, params, run);
  const Pipeline pipeline(reference, model ? model->compared_indexed() : compared, core_points, params, core_normals,
                          run, in_place, set_up, model ? &*model : nullptr);
  const auto& order = pipeline.core_order();
  const Octree& slots = pipeline.reference_tree();
  // With two threads the team has just built the indexes: it is awake (build_indexes). Core
  // points that are the reference ordered in place: row k is the point original_index(k).
  detail::parallel_blocks<Scratch>(
      core_points.size(), run,
      [&](std::size_t begin, std::size_t end, Scratch& s, detail::Pulse& pulse) {
        for (std::size_t k = begin; k < end; ++k) {
          if (in_place.core_in_slots)
            pipeline.run(core_points[k], slots.original_index(k), result, s, pulse);
          else
            pipeline.run(core_points[order[k]], order[k], result, s, pulse);
        }
      },
      64, detail::requested_threads(run) >= 2);
  return result;
}

double max_abs_coordinate(const Params& params) {
  return grid_for(params.normal_diameters, params.projection_diameter).max_abs_coordinate();
}

NormalsResult compute_normals(PointsView cloud, PointsView core_points, const Params& params, const RunOptions& run) {
  detail::validate_normal_params(params);
  if (cloud.empty()) throw InvalidArgument("the cloud is empty");
  detail::require_finite_points("core points", core_points);
  const OctreeGrid grid = grid_for(params.normal_diameters, 0.0);
  const Octree tree = index_of(
      cloud, "cloud", grid,
      {.node_moments = params.normal_subsample_spacing <= 0.0, .build_threads = detail::requested_threads(run)});
  const NormalCloud normals(cloud, tree, params, grid);
  NormalsResult out;
  out.resize(core_points.size());
  const auto order = detail::morton_order(core_points);
  detail::parallel_blocks<detail::NormalScratch>(
      core_points.size(), run, [&](std::size_t begin, std::size_t end, detail::NormalScratch& s) {
        for (std::size_t k = begin; k < end; ++k) {
          const std::size_t i = order[k];
          const Vec3 core = core_points[i];
          const NormalEstimate e = normals.estimate(core, s);
          detail::write_normal(detail::from_estimate(e, core, params.orientation), i, out);
          out.count[i] = e.count;
        }
      });
  return out;
}

}  // namespace m3c2
