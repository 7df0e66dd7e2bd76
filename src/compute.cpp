// compute(), compute_normals() and roughness_by_scale(): the per-core-point pipeline of
// section 3.1 (normal, then projection), the confidence of 3.3 / Appendix B and the statuses.

#include <m3c2/m3c2.hpp>

#include "bootstrap.hpp"
#include "confidence.hpp"
#include "octree.hpp"
#include "normals.hpp"
#include "orientation.hpp"
#include "parallel_for.hpp"
#include "plane_fit.hpp"
#include "projection.hpp"
#include "spatial_order.hpp"
#include "statistics.hpp"
#include "thread_limits.hpp"
#include "threads.hpp"
#include "uncertainty.hpp"
#include "validation.hpp"

#include <algorithm>
#include <cmath>
#include <exception>
#include <functional>
#include <memory>
#include <optional>

namespace m3c2 {
namespace {

using detail::Octree;
using detail::OctreeGrid;
using detail::NormalEstimate;
using detail::NormalEstimator;

/// The octree grid of a run (octree.hpp): derived from the scales alone, the normal diameters when
/// there are any, so that compute(), compute_normals() and every tile of a run share it.
OctreeGrid grid_for(const std::vector<double>& normal_diameters, double projection_diameter) {
  if (normal_diameters.empty()) return detail::octree_grid(projection_diameter, 0.0);
  const auto [smallest, largest] = std::minmax_element(normal_diameters.begin(), normal_diameters.end());
  return detail::octree_grid(*smallest, *largest);
}

/// Whether the normals of this cloud are summed from its own index (not a thinned copy's).
bool moments_needed(const Params& params, bool reference) {
  if (params.normal_subsample_spacing > 0.0) return false;
  const NormalSource src = params.normal_source;
  if (src == NormalSource::kMean) return true;
  return reference ? src == NormalSource::kReference || src == NormalSource::kHorizontal
                   : src == NormalSource::kCompared;
}

/// The index of a cloud named `name` ("reference cloud"). Its one pass over the coordinates
/// refuses those beyond the grid's range (NaN and Inf among them); only then is the cloud
/// searched for non-finite ones, to name them first: "NAME has N non-finite coordinates".
Octree index_of(PointsView cloud, const char* name, OctreeGrid grid, bool with_moments) {
  try {
    return Octree(cloud, grid, with_moments, ("the " + std::string(name)).c_str());
  } catch (const InvalidArgument&) {
    detail::require_finite_points(name, cloud);
    throw;
  }
}

/// Both clouds' indexes and the core points' processing order (morton_order), the compared
/// index and the order on a second thread when the run has two: they are independent (the
/// reference index, with its moments, takes about as long as the other two), and each is
/// computed the same way whatever the thread. The second thread is one of the OpenMP team that
/// then runs the core points: a thread of its own would compete with the team's idle threads,
/// which spin for a while after each parallel loop (W1: 11.6 against 7.9 ms in repeated runs).
/// `alongside` (the caller's own set-up) runs after the index of the thread expected to finish
/// first (an index with moments costs about 1.5 times one without, the order about half an index).
std::pair<Octree, Octree> build_indexes(PointsView reference, PointsView compared, PointsView core_points,
                                        const Params& params, OctreeGrid grid, const RunOptions& run,
                                        std::vector<std::uint32_t>& core_order,
                                        const std::function<void()>& alongside) {
  const bool ref_moments = moments_needed(params, true), cmp_moments = moments_needed(params, false);
  detail::OpenMpTeam team(std::min(2, detail::requested_threads(run)));
  if (team.size() < 2) {
    core_order = detail::morton_order(core_points);
    if (alongside) alongside();
    return {index_of(reference, "reference cloud", grid, ref_moments),
            index_of(compared, "compared cloud", grid, cmp_moments)};
  }
  std::optional<Octree> first, second;
  std::exception_ptr failure[2];
  const double work0 = double(reference.size()) * (ref_moments ? 3 : 2),
               work1 = double(compared.size()) * (cmp_moments ? 3 : 2) + double(core_points.size());
  const int lighter = work1 < work0 ? 1 : 0;
#if defined(_OPENMP)
#pragma omp parallel num_threads(2)
#endif
  {
    const int part = detail::thread_num();
    if (part == 0) team.started();
    const bool alone = detail::team_size() < 2;
    try {
      if (part == 0) first.emplace(index_of(reference, "reference cloud", grid, ref_moments));
      if (part == 1 || alone) {
        second.emplace(index_of(compared, "compared cloud", grid, cmp_moments));
        core_order = detail::morton_order(core_points);
      }
      if ((part == lighter || alone) && alongside) alongside();
    } catch (...) {
      failure[part] = std::current_exception();
    }
  }
  for (const auto& f : failure)  // the reference's error first, as in a serial build
    if (f) std::rethrow_exception(f);
  return {std::move(*first), std::move(*second)};
}

/// A cloud for normals, optionally thinned to params.normal_subsample_spacing (5.1: normals on a
/// subsampled cloud barely change and cost far less).
class NormalCloud {
 public:
  NormalCloud(PointsView cloud, const Octree& full_tree, const Params& params, OctreeGrid grid) {
    if (params.normal_subsample_spacing > 0.0) {
      for (const std::uint64_t i : subsample_min_spacing(cloud, params.normal_subsample_spacing))
        for (int a = 0; a < 3; ++a) thinned_.push_back(cloud.coord(i, a));
      own_tree_ = std::make_unique<Octree>(PointsView(thinned_.data(), thinned_.size() / 3), grid, true);
    }
    estimator_.emplace(own_tree_ ? *own_tree_ : full_tree, params);
  }
  NormalEstimate estimate(const Vec3& core, detail::NormalScratch& s) const { return estimator_->estimate(core, s); }

 private:
  std::vector<double> thinned_;
  std::unique_ptr<Octree> own_tree_;
  std::optional<NormalEstimator> estimator_;
};

struct OrientedNormal {
  Vec3 normal = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
  double diameter = std::numeric_limits<double>::quiet_NaN();
  double roughness = std::numeric_limits<double>::quiet_NaN();
  PointStatus status = PointStatus::kOk;
};

OrientedNormal from_estimate(const NormalEstimate& e, const Vec3& core, const Orientation& o) {
  if (e.status != PointStatus::kOk) return {e.normal, e.diameter, e.roughness, e.status};
  return {detail::orient(e.normal, core, o), e.diameter, e.roughness, PointStatus::kOk};
}

/// Rescales `v` to unit length, or reports it unusable (zero, NaN or Inf).
std::optional<Vec3> unit(const Vec3& v, double min_norm) {
  const double n = v.norm();
  if (!std::isfinite(n) || !(n > min_norm)) return std::nullopt;
  return Vec3(v / n);
}

struct Scratch {
  detail::NormalScratch normal;
  detail::ProjectionScratch projection;
  std::vector<double> t1, t2, work;
  std::vector<std::uint32_t> index1, index2;  // per-point uncertainty: the cylinders' points
  detail::MedianWeightCache median_weights;
};

class Pipeline {
 public:
  /// `alongside`: the caller's set-up, run while the indexes are built (build_indexes).
  Pipeline(PointsView reference, PointsView compared, PointsView core_points, const Params& params,
           const std::vector<double>& core_normals, const RunOptions& run, const std::function<void()>& alongside,
           const detail::UncertaintyModel* uncertainty = nullptr)
      : params_(params),
        uncertainty_(uncertainty),
        core_normals_(core_normals),
        grid_(grid_for(params.normal_diameters, params.projection_diameter)),
        trees_(build_indexes(reference, compared, core_points, params, grid_, run, core_order_, alongside)),
        reference_tree_(trees_.first),
        compared_tree_(trees_.second),
        z_(detail::z_critical(params.confidence)) {
    const NormalSource src = params.normal_source;
    if (src == NormalSource::kReference || src == NormalSource::kMean || src == NormalSource::kHorizontal)
      reference_normals_.emplace(reference, reference_tree_, params, grid_);
    if (src == NormalSource::kCompared || src == NormalSource::kMean)
      compared_normals_.emplace(compared, compared_tree_, params, grid_);
  }

  /// The order in which to process the core points (Morton order).
  const std::vector<std::uint32_t>& core_order() const { return core_order_; }

  void run(const Vec3& core, std::size_t i, Result& r, Scratch& s, detail::Pulse& pulse) const {
    const OrientedNormal n = normal_at(core, i, s);
    for (int a = 0; a < 3; ++a) r.normal[3 * i + a] = n.normal(a);
    r.normal_scale[i] = n.diameter;
    r.roughness[i] = n.roughness;
    r.status[i] = n.status;
    if (n.status != PointStatus::kOk) {
      r.normal[3 * i] = r.normal[3 * i + 1] = r.normal[3 * i + 2] = std::numeric_limits<double>::quiet_NaN();
      return;
    }
    detail::project(reference_tree_, compared_tree_, core, n.normal, params_, s.projection, s.t1, s.t2,
                    uncertainty_ ? &s.index1 : nullptr, uncertainty_ ? &s.index2 : nullptr);
    measure(s, i, r, pulse);
    if (uncertainty_ && r.n1[i] > 0 && r.n2[i] > 0) uncertainty_->measure(core, n.normal, s.index1, s.index2, i, r);
  }

 private:
  OrientedNormal normal_at(const Vec3& core, std::size_t i, Scratch& s) const {
    const Orientation& o = params_.orientation;
    switch (params_.normal_source) {
      case NormalSource::kReference: return from_estimate(reference_normals_->estimate(core, s.normal), core, o);
      case NormalSource::kCompared: return from_estimate(compared_normals_->estimate(core, s.normal), core, o);
      case NormalSource::kMean: {
        const OrientedNormal a = from_estimate(reference_normals_->estimate(core, s.normal), core, o);
        if (a.status != PointStatus::kOk) return a;
        const OrientedNormal b = from_estimate(compared_normals_->estimate(core, s.normal), core, o);
        if (b.status != PointStatus::kOk) return {b.normal, a.diameter, a.roughness, b.status};
        // Opposite normals (a surface that turned over) have no mean direction.
        const auto mean = unit(a.normal + b.normal, 1e-6);
        if (!mean) return {a.normal, a.diameter, a.roughness, PointStatus::kDegenerateNormal};
        return {*mean, a.diameter, a.roughness, PointStatus::kOk};
      }
      case NormalSource::kHorizontal: {
        const OrientedNormal a = from_estimate(reference_normals_->estimate(core, s.normal), core, o);
        if (a.status != PointStatus::kOk) return a;
        // A (near-)horizontal surface has no horizontal direction of its own.
        const auto flat = unit(Vec3(a.normal.x(), a.normal.y(), 0.0), 1e-6);
        if (!flat) return {a.normal, a.diameter, a.roughness, PointStatus::kDegenerateNormal};
        const Vec3 oriented = o.points.empty() ? *flat : detail::orient(*flat, core, o);
        return {oriented, a.diameter, a.roughness, PointStatus::kOk};
      }
      case NormalSource::kVertical: return {detail::orient(Vec3::UnitZ(), core, o), NAN, NAN, PointStatus::kOk};
      case NormalSource::kCorePoints: {
        const auto given = unit(Vec3(core_normals_[3 * i], core_normals_[3 * i + 1], core_normals_[3 * i + 2]), 0.0);
        if (!given) return {Vec3::Constant(NAN), NAN, NAN, PointStatus::kDegenerateNormal};
        return {*given, NAN, NAN, PointStatus::kOk};
      }
    }
    return {};
  }

  void measure(Scratch& s, std::size_t i, Result& r, detail::Pulse& pulse) const {
    const auto n1 = static_cast<std::uint32_t>(s.t1.size()), n2 = static_cast<std::uint32_t>(s.t2.size());
    r.n1[i] = n1;
    r.n2[i] = n2;
    if (n1 == 0 || n2 == 0) {
      r.status[i] = n1 == 0 ? PointStatus::kEmptyCylinder1 : PointStatus::kEmptyCylinder2;
      return;
    }
    const detail::Spread a = detail::central_spread(s.t1, params_, s.work, &s.median_weights);
    const detail::Spread b = detail::central_spread(s.t2, params_, s.work, &s.median_weights);
    r.i1[i] = a.centre, r.i2[i] = b.centre, r.sigma1[i] = a.sigma, r.sigma2[i] = b.sigma;
    r.distance[i] = b.centre - a.centre;
    if (uncertainty_) return;  // PM / EP give the LOD (uncertainty_->measure)
    // Eq. (1) is not defined below two points per cloud whatever min_points says (5.2.1).
    if (n1 < std::max(params_.min_points, 2u) || n2 < std::max(params_.min_points, 2u) || !std::isfinite(a.sigma) ||
        !std::isfinite(b.sigma)) {
      r.status[i] = PointStatus::kTooFewPointsForLod;
      return;
    }
    if (params_.lod == Lod::kBootstrap) {
      r.lod[i] = z_ * (detail::bootstrap_sigma(s.t1, s.t2, params_, i, s.work, pulse) + params_.registration_error);
    } else {
      const double critical = detail::critical_value(params_, z_, a.se, n1, b.se, n2);
      r.lod[i] = detail::lod_parametric(critical, a.se, b.se, params_.registration_error);
    }
    r.significant[i] = std::abs(r.distance[i]) > r.lod[i];
    r.status[i] = PointStatus::kOk;
  }

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
  // (index_of); the core points here, unless they are one of the clouds (the default: the
  // reference itself), whose index names its own non-finite coordinates ("reference cloud has
  // ...", not "core points has ...").
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
  const Pipeline pipeline(reference, model ? model->compared_indexed() : compared, core_points, params, core_normals,
                          run, set_up, model ? &*model : nullptr);
  const auto& order = pipeline.core_order();
  // With two threads the team has just built the indexes: it is awake (build_indexes).
  detail::parallel_blocks<Scratch>(
      core_points.size(), run,
      [&](std::size_t begin, std::size_t end, Scratch& s, detail::Pulse& pulse) {
        for (std::size_t k = begin; k < end; ++k) pipeline.run(core_points[order[k]], order[k], result, s, pulse);
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
  const Octree tree = index_of(cloud, "cloud", grid, params.normal_subsample_spacing <= 0.0);
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
          out.status[i] = e.status;
          out.count[i] = e.count;
          if (e.status != PointStatus::kOk) continue;
          const Vec3 n = detail::orient(e.normal, core, params.orientation);
          for (int a = 0; a < 3; ++a) out.normal[3 * i + a] = n(a);
          out.normal_scale[i] = e.diameter;
          out.roughness[i] = e.roughness;
        }
      });
  return out;
}

std::vector<double> roughness_by_scale(PointsView cloud, PointsView core_points, const std::vector<double>& diameters,
                                       Variance variance, std::uint32_t min_points, const RunOptions& run) {
  Params check;
  check.normal_diameters = diameters;
  detail::validate_normal_params(check);
  if (min_points < 3) throw InvalidArgument("min_points must be >= 3 for a plane fit, got " + std::to_string(min_points));
  detail::require_finite_points("core points", core_points);
  std::vector<std::size_t> by_size(diameters.size());
  for (std::size_t k = 0; k < by_size.size(); ++k) by_size[k] = k;
  std::sort(by_size.begin(), by_size.end(), [&](auto a, auto b) { return diameters[a] < diameters[b]; });
  std::vector<double> radii;
  for (const std::size_t k : by_size) radii.push_back(0.5 * diameters[k]);

  const Octree tree = index_of(cloud, "cloud", grid_for(diameters, 0.0), true);
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
                tree.ball_offsets(core_points[i], radii.back(), s.offsets, &s.octree.descent);
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
