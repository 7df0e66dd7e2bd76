#pragma once
// The per-core-point steps of the pipeline (section 3.1): the run's octree grid, the clouds'
// indexes, the normal at a core point and the measurement from its cylinders. Shared by
// compute() (compute.cpp) and the time-series Comparison (series.cpp), so that an epoch of a
// series is computed by the very code of `m3c2 compare`, bit for bit.

#include "index/octree.hpp"
#include "pipeline/normals.hpp"
#include "pipeline/orientation.hpp"
#include "pipeline/projection.hpp"
#include "pipeline/statistics.hpp"
#include "pipeline/validation.hpp"
#include "support/threads.hpp"
#include "uncertainty/bootstrap.hpp"
#include "uncertainty/confidence.hpp"
#include "uncertainty/median_error.hpp"

#include <m3c2/m3c2.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace m3c2::detail {

/// The octree grid of a run (octree.hpp): derived from the scales alone, the normal diameters when
/// there are any, so that compute(), compute_normals() and every tile of a run share it.
inline OctreeGrid grid_for(const std::vector<double>& normal_diameters, double projection_diameter) {
  if (normal_diameters.empty()) return octree_grid(projection_diameter, 0.0);
  const auto [smallest, largest] = std::minmax_element(normal_diameters.begin(), normal_diameters.end());
  return octree_grid(*smallest, *largest);
}

/// Whether the normals of this cloud are summed from its own index (not a thinned copy's).
inline bool moments_needed(const Params& params, bool reference) {
  if (params.normal_subsample_spacing > 0.0) return false;
  const NormalSource src = params.normal_source;
  if (src == NormalSource::kMean) return true;
  return reference ? src == NormalSource::kReference || src == NormalSource::kHorizontal
                   : src == NormalSource::kCompared;
}

/// Whether these parameters let compute() order its clouds in place (RunOptions::
/// order_clouds_in_place): nothing may read them by input order during the run, as normal
/// subsampling (greedy in input order) and the uncertainty models (per-point inputs, EP's moved
/// copy) do.
inline bool may_order_in_place(const Params& params) {
  return params.normal_subsample_spacing <= 0.0 && params.uncertainty == Uncertainty::kEq1;
}

/// The index of a cloud named `name` ("reference cloud"), built as `options` say (its cloud_name
/// becomes "the NAME"). Its one pass over the coordinates refuses those beyond the grid's range
/// (NaN and Inf among them); only then is the cloud searched for non-finite ones, to name them
/// first: "NAME has N non-finite coordinates".
inline Octree index_of(PointsView cloud, const char* name, OctreeGrid grid, OctreeOptions options = {}) {
  const std::string named = "the " + std::string(name);
  options.cloud_name = named.c_str();
  try {
    return Octree(cloud, grid, options);
  } catch (const InvalidArgument&) {
    require_finite_points(name, cloud);
    throw;
  }
}

/// A cloud for normals, optionally thinned to params.normal_subsample_spacing (5.1: normals on a
/// subsampled cloud barely change and cost far less).
class NormalCloud {
 public:
  NormalCloud(PointsView cloud, const Octree& full_tree, const Params& params, OctreeGrid grid) {
    if (params.normal_subsample_spacing > 0.0) {
      for (const std::uint64_t i : subsample_min_spacing(cloud, params.normal_subsample_spacing))
        for (int a = 0; a < 3; ++a) thinned_.push_back(cloud.coord(i, a));
      own_tree_ = std::make_unique<Octree>(PointsView(thinned_.data(), thinned_.size() / 3), grid,
                                           OctreeOptions{.node_moments = true});
    }
    estimator_.emplace(own_tree_ ? *own_tree_ : full_tree, params);
  }
  NormalEstimate estimate(const Vec3& core, NormalScratch& s) const { return estimator_->estimate(core, s); }

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

inline OrientedNormal from_estimate(const NormalEstimate& e, const Vec3& core, const Orientation& o) {
  if (e.status != PointStatus::kOk) return {e.normal, e.diameter, e.roughness, e.status};
  return {orient(e.normal, core, o), e.diameter, e.roughness, PointStatus::kOk};
}

/// Writes core point i's normal step into `r` as compute() and a series' compare() both report it:
/// the normal (NaN unless the status is kOk), the scale chosen, the roughness and the status.
/// Returns whether the core point goes on to its cylinders (section 3.1.3).
inline bool write_normal(const OrientedNormal& n, std::size_t i, Result& r) {
  const bool ok = n.status == PointStatus::kOk;
  for (int a = 0; a < 3; ++a) r.normal[3 * i + a] = ok ? n.normal(a) : std::numeric_limits<double>::quiet_NaN();
  r.normal_scale[i] = n.diameter;
  r.roughness[i] = n.roughness;
  r.status[i] = n.status;
  return ok;
}

/// Writes core point i's normal into `out` as compute_normals() and a series' normals() both
/// report it: the status, and the normal, scale and roughness only where it is kOk (NaN else).
inline void write_normal(const OrientedNormal& n, std::size_t i, NormalsResult& out) {
  out.status[i] = n.status;
  if (n.status != PointStatus::kOk) return;
  for (int a = 0; a < 3; ++a) out.normal[3 * i + a] = n.normal(a);
  out.normal_scale[i] = n.diameter;
  out.roughness[i] = n.roughness;
}

/// Rescales `v` to unit length, or reports it unusable (zero, NaN or Inf).
inline std::optional<Vec3> unit(const Vec3& v, double min_norm) {
  const double n = v.norm();
  if (!std::isfinite(n) || !(n > min_norm)) return std::nullopt;
  return Vec3(v / n);
}

struct Scratch {
  NormalScratch normal;
  ProjectionScratch projection;
  std::vector<double> t1, t2, work;
  std::vector<std::uint32_t> index1, index2;  // per-point uncertainty: the cylinders' points
  MedianWeightCache median_weights;
};

/// The oriented normal at core point i (index `i` into `core_normals`) by params.normal_source;
/// `reference` / `compared` are the normal clouds that source reads (null otherwise).
inline OrientedNormal normal_at(const Vec3& core, std::size_t i, const Params& params, const NormalCloud* reference,
                                const NormalCloud* compared, const std::vector<double>& core_normals,
                                NormalScratch& s) {
  const Orientation& o = params.orientation;
  switch (params.normal_source) {
    case NormalSource::kReference: return from_estimate(reference->estimate(core, s), core, o);
    case NormalSource::kCompared: return from_estimate(compared->estimate(core, s), core, o);
    case NormalSource::kMean: {
      const OrientedNormal a = from_estimate(reference->estimate(core, s), core, o);
      if (a.status != PointStatus::kOk) return a;
      const OrientedNormal b = from_estimate(compared->estimate(core, s), core, o);
      if (b.status != PointStatus::kOk) return {b.normal, a.diameter, a.roughness, b.status};
      // Opposite normals (a surface that turned over) have no mean direction.
      const auto mean = unit(a.normal + b.normal, 1e-6);
      if (!mean) return {a.normal, a.diameter, a.roughness, PointStatus::kDegenerateNormal};
      return {*mean, a.diameter, a.roughness, PointStatus::kOk};
    }
    case NormalSource::kHorizontal: {
      const OrientedNormal a = from_estimate(reference->estimate(core, s), core, o);
      if (a.status != PointStatus::kOk) return a;
      // A (near-)horizontal surface has no horizontal direction of its own.
      const auto flat = unit(Vec3(a.normal.x(), a.normal.y(), 0.0), 1e-6);
      if (!flat) return {a.normal, a.diameter, a.roughness, PointStatus::kDegenerateNormal};
      const Vec3 oriented = o.points.empty() ? *flat : orient(*flat, core, o);
      return {oriented, a.diameter, a.roughness, PointStatus::kOk};
    }
    case NormalSource::kVertical: return {orient(Vec3::UnitZ(), core, o), NAN, NAN, PointStatus::kOk};
    case NormalSource::kCorePoints: {
      const auto given = unit(Vec3(core_normals[3 * i], core_normals[3 * i + 1], core_normals[3 * i + 2]), 0.0);
      if (!given) return {Vec3::Constant(NAN), NAN, NAN, PointStatus::kDegenerateNormal};
      return {*given, NAN, NAN, PointStatus::kOk};
    }
  }
  return {};
}

/// One cloud's cylinder as measure() uses it: its count and, when it holds points, the centre
/// and spread of its offsets (a function of the offsets alone, so that a time series computes
/// the reference's once for all epochs).
struct CylinderSummary {
  std::uint32_t n = 0;
  Spread spread;
};

inline CylinderSummary summarise(const std::vector<double>& t, const Params& params, Scratch& s) {
  if (t.empty()) return {};
  return {static_cast<std::uint32_t>(t.size()), central_spread(t, params, s.work, &s.median_weights)};
}

/// The count alone, where the other cloud's cylinder is empty and no spread is measured.
inline CylinderSummary counted(const std::vector<double>& t) { return {static_cast<std::uint32_t>(t.size()), {}}; }

/// Section 3.1.3 step 3 and 3.3: the distance, spreads, LOD and significance of core point i
/// from its cylinders' summaries `a` (reference) and `b` (compared); z = z_critical(params.
/// confidence). The bootstrap LOD also reads the offsets themselves, s.t1 and s.t2. With
/// `lod_by_model` (per-point uncertainty, PM / EP) only the distance and spreads: the model
/// gives the LOD. `pulse` lets a long bootstrap be cancelled inside the core point (pulse.hpp).
inline void measure(const Params& params, double z, bool lod_by_model, const CylinderSummary& a,
                    const CylinderSummary& b, Scratch& s, std::size_t i, Result& r, Pulse& pulse) {
  const std::uint32_t n1 = a.n, n2 = b.n;
  r.n1[i] = n1;
  r.n2[i] = n2;
  if (n1 == 0 || n2 == 0) {
    r.status[i] = n1 == 0 ? PointStatus::kEmptyCylinder1 : PointStatus::kEmptyCylinder2;
    return;
  }
  r.i1[i] = a.spread.centre, r.i2[i] = b.spread.centre, r.sigma1[i] = a.spread.sigma, r.sigma2[i] = b.spread.sigma;
  r.distance[i] = b.spread.centre - a.spread.centre;
  if (lod_by_model) return;  // PM / EP: the model gives the LOD
  // Eq. (1) is not defined below two points per cloud whatever min_points says (5.2.1).
  if (n1 < std::max(params.min_points, 2u) || n2 < std::max(params.min_points, 2u) || !std::isfinite(a.spread.sigma) ||
      !std::isfinite(b.spread.sigma)) {
    r.status[i] = PointStatus::kTooFewPointsForLod;
    return;
  }
  // The LOD and the test it expresses: `significant` and `p_value` decided together (p_value.hpp).
  const LodTest test = params.lod == Lod::kBootstrap
                           ? bootstrap_test(params, z, bootstrap_sigma(s.t1, s.t2, params, i, s.work, pulse))
                           : parametric_test(params, z, a.spread.se, n1, b.spread.se, n2);
  r.lod[i] = test.lod;
  decide(test, 1.0 - params.confidence, i, r);
  r.status[i] = PointStatus::kOk;
}

/// measure() from the cylinders' offsets s.t1 and s.t2.
inline void measure(const Params& params, double z, bool lod_by_model, Scratch& s, std::size_t i, Result& r,
                    Pulse& pulse) {
  if (s.t1.empty() || s.t2.empty()) {  // no spread needed
    measure(params, z, lod_by_model, counted(s.t1), counted(s.t2), s, i, r, pulse);
    return;
  }
  const CylinderSummary a = summarise(s.t1, params, s), b = summarise(s.t2, params, s);
  measure(params, z, lod_by_model, a, b, s, i, r, pulse);
}

}  // namespace m3c2::detail
