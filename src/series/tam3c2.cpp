// Time-adaptive M3C2 (include/m3c2/tam3c2.hpp; docs/series.md, "TAM3C2"; Huang et al., ISPRS
// Annals 2026). The definitions are the paper's as its authors' code (xyuhuang/py4dgeo,
// tam3c2.py) computes them; the spatial search is the engine's k-d tree (index/kdtree.hpp), each
// epoch indexed once: its balls for the normal's spheres, its boxes pruned by the cylinder's
// bounds (index/cylinder.hpp) for the projection cylinders.
//
//   order     epochs by |t_e - t_c|, ties by time order (earlier first): nearest in time first
//   aggregate walk the order while |t_e - t_c| <= W, adding each epoch's points in the
//             neighbourhood, until the side holds min_points points
//   normal    PCA of the aggregated sphere (covariance / N), smallest eigenvector towards
//             the core point's orientation; planarity (l1 - l0) / l2 (0 when l2 <= 1e-12); the combination
//             (radius, ratio) of highest planarity wins, W = (time range) * ratio for this contest
//   distance  m2 - m1, m the (weighted) mean of (p - c) . n on each side
//   LOD       z sqrt(s1^2 / n1 + s2^2 / n2) + reg, n = max(1, count or (sum w)^2 / sum w^2)
//
// Ours (issue 41, off by default): the breaks keep each walk inside its centre's segment
// (tam3c2_breaks.hpp); the fallback gives a short cell the epoch's own M3C2 (fall_back()).

#include <m3c2/errors.hpp>
#include <m3c2/tam3c2.hpp>

#include "index/cylinder.hpp"
#include "index/kdtree.hpp"
#include "index/spatial_order.hpp"
#include "support/parallel_for.hpp"
#include "tam3c2_breaks.hpp"
#include "uncertainty/confidence.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>

namespace m3c2 {

struct Tam3c2Pool::Impl {
  std::vector<PointsView> clouds;
  std::vector<detail::KdTree> trees;
};

Tam3c2Pool::Tam3c2Pool(std::vector<PointsView> clouds, std::vector<double> times)
    : times_(std::move(times)), impl_(std::make_unique<Impl>()) {
  if (clouds.size() != times_.size()) throw InvalidArgument("TAM3C2: one time per epoch of the pool");
  for (double t : times_)
    if (!std::isfinite(t)) throw InvalidArgument("TAM3C2: every epoch of the pool needs a finite time");
  impl_->clouds = std::move(clouds);
  impl_->trees.reserve(impl_->clouds.size());
  for (const PointsView& c : impl_->clouds) impl_->trees.emplace_back(c);
}
Tam3c2Pool::~Tam3c2Pool() = default;
Tam3c2Pool::Tam3c2Pool(Tam3c2Pool&&) noexcept = default;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// One side's aggregated neighbourhood: the points (x, y, z) and each point's dt = t_e - t_c.
/// `ends`: the count after each epoch added, in walk order.
struct Side {
  std::vector<double> xyz, dt;
  std::vector<std::size_t> ends;
  std::uint32_t epochs = 0;
  std::size_t count() const { return dt.size(); }
  void clear() { xyz.clear(), dt.clear(), ends.clear(), epochs = 0; }
  /// The side a walk capped at `window` would have made: the walk is in order of |dt|, so its
  /// epochs within the window are a prefix of this uncapped walk's.
  void prefix_of(const Side& full, double window) {
    clear();
    std::size_t k = 0;
    while (k < full.ends.size() && std::abs(full.dt[full.ends[k] - 1]) <= window) ++k;
    const std::size_t n = k ? full.ends[k - 1] : 0;
    xyz.assign(full.xyz.begin(), full.xyz.begin() + std::ptrdiff_t(3 * n));
    dt.assign(full.dt.begin(), full.dt.begin() + std::ptrdiff_t(n));
    ends.assign(full.ends.begin(), full.ends.begin() + std::ptrdiff_t(k));
    epochs = std::uint32_t(k);
  }
};

/// What a core point's cells share: its position, normal, window ratio and the reference's side
/// walked without a cap (each target's window takes a prefix of it).
struct CorePoint {
  std::size_t index = 0;
  Vec3 c, normal;
  double ratio = 0.0;
  Side reference;
  std::vector<std::uint32_t> segment;  ///< per pool epoch, with the breaks; else empty
};

struct Scratch {
  std::vector<std::uint32_t> found;
  Side a, b;
  std::vector<CorePoint> block;
  std::vector<double> w1, w2, proj, finite;
};

/// The epochs a walk may take: all (no breaks), or those of the centre's segment.
struct Segment {
  const std::uint32_t* of = nullptr;  ///< per pool epoch; nullptr: no breaks
  std::uint32_t keep = 0;
  bool admits(std::size_t e) const { return of == nullptr || of[e] == keep; }
};
Segment segment_of(const CorePoint& cp, std::size_t centre) {
  return cp.segment.empty() ? Segment{} : Segment{cp.segment.data(), cp.segment[centre]};
}

/// The pool's indices nearest in time to `centre` first; equal distances in pool order (time
/// order for a pool sorted by time). Made once per centre epoch: every core point walks it.
std::vector<std::size_t> nearest_first(const std::vector<double>& times, double centre) {
  std::vector<std::size_t> order(times.size());
  std::iota(order.begin(), order.end(), std::size_t(0));
  std::stable_sort(order.begin(), order.end(), [&](std::size_t i, std::size_t j) {
    return std::abs(times[i] - centre) < std::abs(times[j] - centre);
  });
  return order;
}

/// Aggregates around time `centre` (nearest first, within `window`, until min_points, only epochs
/// `segment` admits); `query` appends the indices of an epoch's points in the neighbourhood (a
/// sphere or a cylinder).
template <class Query>
void aggregate(const Tam3c2Pool& pool, const std::vector<std::size_t>& order, double centre, double window,
               std::uint32_t min_points, Segment segment, Scratch& s, Side& side, Query&& query) {
  side.clear();
  for (std::size_t e : order) {
    const double dt = pool.times()[e] - centre;
    if (std::abs(dt) > window) break;
    if (!segment.admits(e)) continue;
    s.found.clear();
    query(pool.impl().trees[e], s.found);
    if (s.found.empty()) continue;
    std::sort(s.found.begin(), s.found.end());  // the cloud's order, whatever the tree's
    const PointsView cloud = pool.impl().clouds[e];
    for (std::uint32_t i : s.found) {
      const double* p = cloud.data() + 3 * std::size_t(i);
      side.xyz.insert(side.xyz.end(), p, p + 3);
      side.dt.push_back(dt);
    }
    ++side.epochs;
    side.ends.push_back(side.count());
    if (side.count() >= min_points) break;
  }
}

/// Planarity and normal of the points (tam3c2_readme.md 4.3); -inf with fewer than 3 points.
double planarity(const Side& side, const Vec3& orientation, Vec3& normal) {
  const std::size_t n = side.count();
  if (n < 3) return -std::numeric_limits<double>::infinity();
  Vec3 mean = Vec3::Zero();
  for (std::size_t i = 0; i < n; ++i) mean += Vec3(side.xyz[3 * i], side.xyz[3 * i + 1], side.xyz[3 * i + 2]);
  mean /= double(n);
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 d = Vec3(side.xyz[3 * i], side.xyz[3 * i + 1], side.xyz[3 * i + 2]) - mean;
    cov += d * d.transpose();
  }
  cov /= double(n);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);  // ascending eigenvalues
  const Vec3 l = eig.eigenvalues();
  normal = eig.eigenvectors().col(0);
  if (normal.dot(orientation) < 0.0) normal = -normal;
  return l[2] > 1e-12 ? (l[1] - l[0]) / l[2] : 0.0;
}

/// The weight of each point of a side (tam3c2_readme.md 4.5), empty for unweighted.
void weights(const Tam3c2Params& p, const Side& side, const Vec3& c, const Vec3& n, double window,
             std::vector<double>& w) {
  w.clear();
  if (p.weights == Tam3c2Weights::kNone) return;
  const double win = window * p.space_time_ratio;
  const double sigma = p.sigma_ratio > 0.0 ? p.sigma_ratio : 1.0;
  bool any = false;
  for (std::size_t i = 0; i < side.count(); ++i) {
    const double* q = side.xyz.data() + 3 * i;
    const double dx = q[0] - c.x(), dy = q[1] - c.y(), dz = q[2] - c.z();
    const double along = dx * n.x() + dy * n.y() + dz * n.z();
    const double radial = std::sqrt(std::max(dx * dx + dy * dy + dz * dz - along * along, 0.0));
    const double us = radial / p.cylinder_radius, ut = std::abs(side.dt[i]) / win;
    double ws = 1.0, wt = 1.0;
    if (p.weights == Tam3c2Weights::kLinear) {
      ws = std::clamp(1.0 - us, 0.0, 1.0);
      if (win > 0.0) wt = std::clamp(1.0 - ut, 0.0, 1.0);
    } else {
      ws = std::exp(-(us * us) / (2.0 * sigma * sigma));
      if (win > 0.0) wt = std::exp(-(ut * ut) / (2.0 * sigma * sigma));
    }
    w.push_back(ws * wt);
    any = any || w.back() > 0.0;
  }
  if (!any) std::fill(w.begin(), w.end(), 1.0);  // all weights vanished: the side unweighted
}

struct Moments {
  double mean, spread, n;
};

/// Mean, spread and n of the side's projections on n (tam3c2_readme.md 4.6).
Moments side_moments(const Side& side, const std::vector<double>& w, const Vec3& c, const Vec3& n,
                     std::vector<double>& proj) {
  const std::size_t k = side.count();
  proj.resize(k);
  for (std::size_t i = 0; i < k; ++i) {
    const double* q = side.xyz.data() + 3 * i;
    proj[i] = (q[0] - c.x()) * n.x() + (q[1] - c.y()) * n.y() + (q[2] - c.z()) * n.z();
  }
  Moments m{};
  if (w.empty()) {
    double sum = 0.0;
    for (double v : proj) sum += v;
    m.mean = sum / double(k);
    double ss = 0.0;
    for (double v : proj) ss += (v - m.mean) * (v - m.mean);
    m.spread = std::sqrt(ss / double(k - 1));  // the sample standard deviation (k >= 2)
    m.n = double(k);
  } else {
    double sw = 0.0, swp = 0.0, sw2 = 0.0;
    for (std::size_t i = 0; i < k; ++i) sw += w[i], swp += w[i] * proj[i], sw2 += w[i] * w[i];
    m.mean = swp / sw;
    double ss = 0.0;
    for (std::size_t i = 0; i < k; ++i) ss += w[i] * (proj[i] - m.mean) * (proj[i] - m.mean);
    m.spread = std::sqrt(ss / sw);
    m.n = sw2 > 0.0 ? sw * sw / sw2 : double(k);  // Kish's effective sample size
  }
  m.n = std::max(m.n, 1.0);
  return m;
}

/// Tam3c2Fallback::kM3c2: a cell whose windows left a side short of min_points, or without a
/// distance, takes the epoch's own M3C2 where that has a distance (issue 41: where no window
/// reaches --required-points, the plain M3C2 value and LOD of that epoch). False: TAM3C2's own.
bool fall_back(const Tam3c2Params& p, const Tam3c2Epochwise& m, std::size_t at, const Side& a, const Side& b,
               Tam3c2Result& out, std::size_t o) {
  if (p.fallback != Tam3c2Fallback::kM3c2) return false;
  const bool reached = a.count() >= p.min_points && b.count() >= p.min_points && a.count() >= 2 && b.count() >= 2;
  if (reached || !std::isfinite(m.distance[at])) return false;
  out.distance[o] = m.distance[at], out.lod[o] = m.lod[at], out.n1[o] = m.n1[at], out.n2[o] = m.n2[at];
  out.significant[o] = std::isnan(m.significant[at]) ? std::int8_t(-1) : std::int8_t(m.significant[at] != 0.0);
  out.source[o] = std::uint8_t(Tam3c2Source::kEpoch);
  return true;
}

/// The LOD of two sides (Tam3c2Lod). kZ keeps the reference's arithmetic; kT and kAuto first make
/// a weighted side's spread unbiased (x n / (n - 1), Kish's n; +inf at n <= 1: one point's weight
/// bounds nothing) and take Welch's t at the sides' (effective) n where the rule asks for it.
/// `z`: the normal quantile at p.confidence (detail::z_critical, computed once per run).
double side_lod(const Tam3c2Params& p, double z, Moments& m1, bool weighted1, Moments& m2, bool weighted2) {
  const double inf = std::numeric_limits<double>::infinity();
  if (p.lod != Tam3c2Lod::kZ)
    for (auto [m, weighted] : {std::pair<Moments*, bool>{&m1, weighted1}, {&m2, weighted2}})
      if (weighted) m->spread = m->n > 1.0 ? m->spread * std::sqrt(m->n / (m->n - 1.0)) : inf;
  const double v1 = m1.spread * m1.spread / m1.n, v2 = m2.spread * m2.spread / m2.n;
  double critical = z;
  if (p.lod == Tam3c2Lod::kT || (p.lod == Tam3c2Lod::kAuto && (m1.n < 30.0 || m2.n < 30.0))) {
    if (v1 + v2 == 0.0) return p.registration_error;  // no spread: no quantile is needed
    const double dof = detail::welch_dof(std::sqrt(v1), m1.n, std::sqrt(v2), m2.n);
    critical = inf;  // no degrees of freedom, or so few that the quantile overflows: nothing is bounded
    if (std::isfinite(dof) && dof > 0.0) try {
        critical = detail::t_critical(p.confidence, dof);
      } catch (const std::overflow_error&) {
      }
  }
  return critical * std::sqrt(v1 + v2) + p.registration_error;
}

void check(const Tam3c2Params& p, const Tam3c2Pool& pool, std::size_t reference,
           const std::vector<std::size_t>& targets, const Tam3c2Epochwise& epochwise) {
  if (p.normal_radii.empty() || p.window_ratios.empty())
    throw InvalidArgument("TAM3C2 needs at least one normal radius and one window ratio");
  for (double r : p.normal_radii)
    if (!(r > 0.0 && std::isfinite(r))) throw InvalidArgument("TAM3C2: normal radii must be finite and > 0");
  for (double r : p.window_ratios)
    if (!(r > 0.0 && r <= 1.0)) throw InvalidArgument("TAM3C2: window ratios must be in (0, 1]");
  if (!(p.cylinder_radius > 0.0 && std::isfinite(p.cylinder_radius)) ||
      !(p.max_distance > 0.0 && std::isfinite(p.max_distance)))
    throw InvalidArgument("TAM3C2: the cylinder's radius and half-length must be finite and > 0");
  if (p.min_points < 1) throw InvalidArgument("TAM3C2: min_points must be >= 1");
  if (!(p.orientation.allFinite() && p.orientation.norm() > 0.0))
    throw InvalidArgument("TAM3C2: the orientation must be a finite, non-zero direction");
  if (!(p.space_time_ratio > 0.0 && std::isfinite(p.space_time_ratio)) || !std::isfinite(p.sigma_ratio))
    throw InvalidArgument("TAM3C2: space_time_ratio must be finite and > 0, sigma_ratio finite");
  if (!(p.registration_error >= 0.0)) throw InvalidArgument("TAM3C2: the registration error must be >= 0");
  if (!(p.confidence > 0.0 && p.confidence < 1.0)) throw InvalidArgument("TAM3C2: the confidence must be in (0, 1)");
  if (reference >= pool.size()) throw InvalidArgument("TAM3C2: the reference is not an epoch of the pool");
  if (epochwise.empty() && (p.fallback != Tam3c2Fallback::kNone || p.breaks != Tam3c2Breaks::kNone))
    throw InvalidArgument("TAM3C2: the fallback and the window breaks need the epochs' own M3C2");
  if (!epochwise.empty() && !(epochwise.lod && epochwise.significant && epochwise.n1 && epochwise.n2))
    throw InvalidArgument("TAM3C2: the epochs' own M3C2 needs distance, lod, significant, n1 and n2");
  const ChangePointParams& cp = p.change_points;
  if (p.breaks != Tam3c2Breaks::kNone && !(cp.width >= 2 && cp.jump >= 1 && cp.penalty > 0.0))
    throw InvalidArgument("TAM3C2: the breaks' change points need a width >= 2, a jump >= 1 and a penalty > 0");
  for (std::size_t t : targets)
    if (t >= pool.size()) throw InvalidArgument("TAM3C2: a target is not an epoch of the pool");
}

}  // namespace

Tam3c2Result tam3c2(const Tam3c2Params& p, const Tam3c2Pool& pool, std::size_t reference,
                    const std::vector<std::size_t>& targets, PointsView core, PointsView orientations,
                    const Tam3c2Epochwise& epochwise, const RunOptions& run) {
  check(p, pool, reference, targets, epochwise);
  if (!orientations.empty() && orientations.size() != core.size())
    throw InvalidArgument("TAM3C2: one orientation per core point, or none");
  // The side each core point's normal points to, of unit length (also the normal of a core point
  // without one, the scale contest's fallback).
  const auto orientation_of = [&](std::size_t i) {
    if (!orientations.empty()) {
      const Vec3 o = orientations[i];
      const double norm = o.norm();
      if (std::isfinite(norm) && norm > 0.0) return Vec3(o / norm);
    }
    return Vec3(p.orientation / p.orientation.norm());
  };
  const std::size_t nc = core.size(), nt = targets.size();
  const std::size_t ratios = p.window_ratios.size();
  const auto [lo, hi] = std::minmax_element(pool.times().begin(), pool.times().end());
  double range = pool.size() ? *hi - *lo : 0.0;
  if (!(range > 0.0)) range = 1.0;  // one time: any positive window takes only that time
  const double t_ref = pool.times()[reference];
  const double r2 = p.cylinder_radius * p.cylinder_radius;
  const double z = detail::z_critical(p.confidence);  // the one owner of the LOD's quantile

  // The walk of each centre: the reference's, and each target's.
  const std::vector<std::size_t> ref_order = nearest_first(pool.times(), t_ref);
  std::vector<std::vector<std::size_t>> target_order;
  for (std::size_t t : targets) target_order.push_back(nearest_first(pool.times(), pool.times()[t]));

  Tam3c2Result out;
  out.normal.assign(3 * nc, kNaN);
  out.scale.assign(nc, -1);
  for (auto* v : {&out.distance, &out.lod, &out.spread1, &out.spread2, &out.n1, &out.n2}) v->assign(nc * nt, kNaN);
  for (auto* v : {&out.epochs1, &out.epochs2, &out.points1, &out.points2}) v->assign(nc * nt, 0u);
  out.significant.assign(nc * nt, std::int8_t(-1));
  out.source.assign(nc * nt, std::uint8_t(Tam3c2Source::kNone));
  const std::size_t np = pool.size();
  // The pool in time order (ties: pool order), the breaks' series order.
  std::vector<std::size_t> by_time(np);
  std::iota(by_time.begin(), by_time.end(), std::size_t(0));
  std::stable_sort(by_time.begin(), by_time.end(),
                   [&](std::size_t i, std::size_t j) { return pool.times()[i] < pool.times()[j]; });

  // The points of a projection cylinder (the reference code's membership test, radial^2 = |v|^2 -
  // along^2), the tree's boxes pruned by the cylinder's bounds (index/cylinder.hpp).
  const auto cylinder_of = [&](const Vec3& c, const Vec3& normal) {
    return [&p, r2, c, normal](const detail::KdTree& tree, std::vector<std::uint32_t>& found) {
      const detail::Cylinder bounds{c, normal, p.cylinder_radius, -p.max_distance, p.max_distance};
      tree.select([&](const auto& lo, const auto& hi) { return !detail::box_may_meet(lo, hi, bounds); },
                  [&](const double* q) {
                    const double dx = q[0] - c.x(), dy = q[1] - c.y(), dz = q[2] - c.z();
                    const double along = dx * normal.x() + dy * normal.y() + dz * normal.z();
                    return dx * dx + dy * dy + dz * dz - along * along <= r2 && std::abs(along) <= p.max_distance;
                  },
                  found);
    };
  };

  // A core point's normal (the scale contest on the reference, 4.4: the most planar aggregated
  // sphere), its ratio and its reference side.
  const auto prepare = [&](std::size_t i, Scratch& s, CorePoint& cp) {
    const Vec3 c = core[i], towards = orientation_of(i);
    cp.segment.clear();
    if (p.breaks == Tam3c2Breaks::kChangePoints)
      detail::break_segments(epochwise.distance + i * np, by_time, p.change_points, cp.segment, s.finite);
    const Segment around_reference = segment_of(cp, reference);
    double best = -std::numeric_limits<double>::infinity();
    Vec3 normal = towards;
    std::int32_t chosen = -1;
    for (std::size_t a = 0; a < p.normal_radii.size(); ++a)
      for (std::size_t b = 0; b < ratios; ++b) {
        const double r = p.normal_radii[a];
        aggregate(pool, ref_order, t_ref, range * p.window_ratios[b], p.min_points, around_reference, s, s.a,
                  [&](const detail::KdTree& tree, std::vector<std::uint32_t>& found) { tree.ball(c, r, found); });
        Vec3 nrm = towards;
        const double pl = planarity(s.a, towards, nrm);
        if (pl > best) best = pl, normal = nrm, chosen = std::int32_t(a * ratios + b);
      }
    for (int k = 0; k < 3; ++k) out.normal[3 * i + k] = normal[k];
    out.scale[i] = chosen;
    cp.index = i, cp.c = c, cp.normal = normal;
    cp.ratio = p.window_ratios[chosen < 0 ? 0 : std::size_t(chosen) % ratios];
    aggregate(pool, ref_order, t_ref, std::numeric_limits<double>::infinity(), p.min_points, around_reference, s,
              cp.reference, cylinder_of(c, normal));
  };

  // One cell: the core point's distance and LOD at target j.
  const auto cell = [&](const CorePoint& cp, std::size_t j, Scratch& s) {
    const double t_tgt = pool.times()[targets[j]];
    double gap = std::abs(t_tgt - t_ref);
    if (gap == 0.0) gap = range;  // the target at the reference's time: the whole range (4.7)
    const double window = gap * cp.ratio;
    s.a.prefix_of(cp.reference, window);
    aggregate(pool, target_order[j], t_tgt, window, p.min_points, segment_of(cp, targets[j]), s, s.b,
              cylinder_of(cp.c, cp.normal));
    const std::size_t o = cp.index * nt + j;
    out.epochs1[o] = s.a.epochs, out.epochs2[o] = s.b.epochs;
    out.points1[o] = std::uint32_t(s.a.count()), out.points2[o] = std::uint32_t(s.b.count());
    if (fall_back(p, epochwise, cp.index * np + targets[j], s.a, s.b, out, o)) return;
    if (s.a.count() < 2 || s.b.count() < 2) return;  // no spread on a side: no distance
    weights(p, s.a, cp.c, cp.normal, window, s.w1);
    weights(p, s.b, cp.c, cp.normal, window, s.w2);
    Moments m1 = side_moments(s.a, s.w1, cp.c, cp.normal, s.proj);
    Moments m2 = side_moments(s.b, s.w2, cp.c, cp.normal, s.proj);
    out.distance[o] = m2.mean - m1.mean;
    out.lod[o] = side_lod(p, z, m1, !s.w1.empty(), m2, !s.w2.empty());
    out.spread1[o] = m1.spread, out.spread2[o] = m2.spread, out.n1[o] = m1.n, out.n2[o] = m2.n;
    out.significant[o] = std::int8_t(std::abs(out.distance[o]) > out.lod[o]);
    out.source[o] = std::uint8_t(Tam3c2Source::kWindows);
  };

  // Blocks of core points in Morton order (neighbours together), each block walked target by
  // target: the trees' paths and leaves an epoch has around the block stay in cache while every
  // core point of the block uses them (core point by core point, a thousand epochs' neighbourhoods
  // do not fit in cache, and the walk waits for memory). Every cell's arithmetic is its own,
  // written by index: the same bits in any order, block size or thread count.
  const std::vector<std::uint32_t> visit = detail::morton_order(core);
  constexpr std::size_t kBlock = 64;
  detail::parallel_blocks<Scratch>(
      nc, run,
      [&](std::size_t begin, std::size_t end, Scratch& s) {
        s.block.resize(end - begin);
        for (std::size_t k = begin; k < end; ++k) prepare(visit[k], s, s.block[k - begin]);
        for (std::size_t j = 0; j < nt; ++j)
          for (const CorePoint& cp : s.block) cell(cp, j, s);
      },
      kBlock);
  return out;
}

}  // namespace m3c2
