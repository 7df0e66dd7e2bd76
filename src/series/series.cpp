// Comparison: the reference's index and the core points' normals kept across the epochs of a
// series; each compare() runs the per-core-point steps of compute() (core_point.hpp) against
// the epoch's own index, so that its bits are those of compute().

#include <m3c2/series.hpp>

#include "index/spatial_order.hpp"
#include "pipeline/core_point.hpp"
#include "support/parallel_for.hpp"

namespace m3c2 {

struct Comparison::State {
  Params params;
  std::vector<double> core;          // row-major xyz, copied
  std::vector<double> core_normals;  // kCorePoints only
  detail::OctreeGrid grid;
  std::optional<detail::Octree> reference;
  std::vector<std::uint32_t> order;  // Morton order of the core points (spatial_order.hpp)
  std::vector<detail::OrientedNormal> normals;
  // The reference's cylinder at each core point, the same for every epoch, summarised once:
  // the full depth and, with kTwoPass, the first pass (project_first_pass). measure() reads no
  // more of it, except the bootstrap, which resamples the offsets: then it is searched again.
  bool reference_summarised = false;
  std::vector<detail::CylinderSummary> reference_full, reference_first;
  double z = 0.0;

  PointsView core_view() const { return {core.data(), core.size() / 3}; }
};

Comparison::Comparison(PointsView reference, PointsView core_points, const Params& params, const RunOptions& run,
                       const std::vector<double>& core_normals)
    : state_(std::make_unique<State>()) {
  detail::validate_params(params);
  if (params.normal_source == NormalSource::kCompared || params.normal_source == NormalSource::kMean)
    throw InvalidArgument(
        "a series computes the normals once, from the reference: normal source 'compared' or "
        "'mean' would depend on each epoch; use 'reference', 'horizontal', 'vertical' or 'core'");
  if (params.uncertainty != Uncertainty::kEq1)
    throw InvalidArgument(
        "a series computes the LOD of eq. (1): per-point uncertainty (M3C2-PM, M3C2-EP) needs each "
        "epoch's own inputs and is not available for a series");
  if (reference.empty()) throw InvalidArgument("the reference cloud is empty");
  detail::require_finite_points("core points", core_points);
  if (params.normal_source == NormalSource::kCorePoints && core_normals.size() != 3 * core_points.size())
    throw InvalidArgument("core_normals must hold 3 values per core point (" + std::to_string(3 * core_points.size()) +
                          "), got " + std::to_string(core_normals.size()));
  State& s = *state_;
  s.params = params;
  s.core.resize(3 * core_points.size());
  for (std::size_t i = 0; i < core_points.size(); ++i)
    for (int a = 0; a < 3; ++a) s.core[3 * i + a] = core_points.coord(i, a);
  if (params.normal_source == NormalSource::kCorePoints) s.core_normals = core_normals;
  s.grid = detail::grid_for(params.normal_diameters, params.projection_diameter);
  s.reference.emplace(detail::index_of(
      reference, "reference cloud", s.grid,
      {.node_moments = detail::moments_needed(params, true), .build_threads = detail::requested_threads(run)}));
  s.order = detail::morton_order(s.core_view());
  s.z = detail::z_critical(params.confidence);

  std::optional<detail::NormalCloud> reference_normals;
  const NormalSource src = params.normal_source;
  if (src == NormalSource::kReference || src == NormalSource::kHorizontal)
    reference_normals.emplace(reference, *s.reference, s.params, s.grid);
  s.normals.resize(core_points.size());
  const bool two_pass = params.depth_search == DepthSearch::kTwoPass;
  s.reference_summarised = params.lod != Lod::kBootstrap;
  if (s.reference_summarised) {
    s.reference_full.resize(core_points.size());
    if (two_pass) s.reference_first.resize(core_points.size());
  }
  const PointsView core = s.core_view();
  detail::parallel_blocks<detail::Scratch>(
      core.size(), run, [&](std::size_t begin, std::size_t end, detail::Scratch& scratch) {
        for (std::size_t k = begin; k < end; ++k) {
          const std::size_t i = s.order[k];
          const detail::OrientedNormal& n = s.normals[i] =
              detail::normal_at(core[i], i, s.params, reference_normals ? &*reference_normals : nullptr, nullptr,
                                s.core_normals, scratch.normal);
          if (!s.reference_summarised || n.status != PointStatus::kOk) continue;
          detail::project_full_depth(*s.reference, core[i], n.normal, s.params, scratch.projection, scratch.t1);
          s.reference_full[i] = detail::summarise(scratch.t1, s.params, scratch);
          if (!two_pass) continue;
          detail::project_first_pass(*s.reference, core[i], n.normal, s.params, scratch.projection, scratch.t1);
          s.reference_first[i] = detail::summarise(scratch.t1, s.params, scratch);
        }
      });
}

Comparison::~Comparison() = default;
Comparison::Comparison(Comparison&&) noexcept = default;
Comparison& Comparison::operator=(Comparison&&) noexcept = default;

std::size_t Comparison::size() const { return state_->normals.size(); }

Result Comparison::compare(PointsView compared, const RunOptions& run) const {
  const State& s = *state_;
  if (compared.empty()) throw InvalidArgument("the compared cloud is empty");
  const detail::Octree epoch = detail::index_of(
      compared, "compared cloud", s.grid,
      {.node_moments = detail::moments_needed(s.params, false), .build_threads = detail::requested_threads(run)});
  Result result;
  result.resize(size());
  const PointsView core = s.core_view();
  const bool two_pass = s.params.depth_search == DepthSearch::kTwoPass;
  // The body of compute()'s Pipeline::run with the normal looked up instead of estimated: the
  // same writes (write_normal, measure).
  detail::parallel_blocks<detail::Scratch>(
      core.size(), run, [&](std::size_t begin, std::size_t end, detail::Scratch& scratch, detail::Pulse& pulse) {
        for (std::size_t k = begin; k < end; ++k) {
          const std::size_t i = s.order[k];
          const detail::OrientedNormal& n = s.normals[i];
          if (!detail::write_normal(n, i, result)) continue;
          if (!s.reference_summarised) {
            detail::project(*s.reference, epoch, core[i], n.normal, s.params, scratch.projection, scratch.t1,
                            scratch.t2);
            detail::measure(s.params, s.z, false, scratch, i, result, pulse);
            continue;
          }
          // project()'s rule with the reference's side known: the first pass where it found
          // points in both clouds, else the full depth in both.
          const detail::CylinderSummary* a = &s.reference_full[i];
          if (two_pass && s.reference_first[i].n > 0) {
            detail::project_first_pass(epoch, core[i], n.normal, s.params, scratch.projection, scratch.t2);
            if (!scratch.t2.empty()) a = &s.reference_first[i];
          }
          if (a == &s.reference_full[i])
            detail::project_full_depth(epoch, core[i], n.normal, s.params, scratch.projection, scratch.t2);
          const detail::CylinderSummary b =
              a->n == 0 ? detail::counted(scratch.t2) : detail::summarise(scratch.t2, s.params, scratch);
          detail::measure(s.params, s.z, false, *a, b, scratch, i, result, pulse);
        }
      });
  return result;
}

NormalsResult Comparison::normals() const {
  const State& s = *state_;
  NormalsResult out;
  out.resize(size());
  for (std::size_t i = 0; i < size(); ++i) detail::write_normal(s.normals[i], i, out);
  return out;
}

}  // namespace m3c2
