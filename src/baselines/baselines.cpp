// C2C and C2C_HF baselines (section 3.4, Fig. 4): exact closest point by growing kd-tree balls,
// and the least-squares plane of the closest point's neighbours (CloudCompare's local model).

#include <m3c2/baselines.hpp>
#include <m3c2/errors.hpp>

#include "index/kdtree.hpp"
#include "pipeline/validation.hpp"
#include "support/parallel_for.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace m3c2 {
namespace {

using detail::KdTree;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// Typical point spacing used as the first search radius: sqrt(area / n) with the area spanned by
/// the two largest extents of the bounding box (a surface). Only a starting guess: any positive
/// value gives the same results, a good one gives them faster.
double spacing_guess(PointsView points) {
  Vec3 lo = points[0], hi = points[0];
  for (std::size_t i = 1; i < points.size(); ++i) {
    lo = lo.cwiseMin(points[i]);
    hi = hi.cwiseMax(points[i]);
  }
  Vec3 e = hi - lo;
  std::sort(e.data(), e.data() + 3, std::greater<>());
  const double n = static_cast<double>(points.size());
  double r = e[1] > 0 ? std::sqrt(e[0] * e[1] / n) : e[0] / n;
  if (!(r > 0) || !std::isfinite(r)) r = 1.0;
  return r;
}

struct Scratch {
  std::vector<std::uint32_t> ball;
  std::vector<std::pair<double, std::uint32_t>> ranked;
  // The previous query of this block: its nearest point bounds this query's nearest distance
  // from above (triangle inequality) and its distance bounds it from below.
  bool have_hint = false;
  Vec3 hint_query;
  std::uint32_t hint_nearest = 0;
  double hint_distance = 0;
};

/// The smallest (squared distance, index) in scratch.ball; ball must not be empty.
std::pair<double, std::uint32_t> closest_in_ball(PointsView pts, const Vec3& q,
                                                 const std::vector<std::uint32_t>& ball) {
  std::pair<double, std::uint32_t> best{std::numeric_limits<double>::infinity(), 0};
  for (const std::uint32_t j : ball) {
    const std::pair<double, std::uint32_t> c{detail::squared_distance(pts, j, q), j};
    if (c < best) best = c;
  }
  return best;
}

/// Exact nearest neighbour of q: every point at the nearest distance lies in any ball of at least
/// that radius (the ball test is inclusive and exact), so the result does not depend on the radii
/// tried, only on which is the first non-empty ball.
std::pair<double, std::uint32_t> nearest(const KdTree& tree, const Vec3& q, double r0, Scratch& s) {
  auto search = [&](double r) {
    s.ball.clear();
    tree.ball(q, r, s.ball);
    return !s.ball.empty();
  };
  bool found = false;
  if (s.have_hint) {
    const double ub = std::sqrt(detail::squared_distance(tree.points(), s.hint_nearest, q)) * (1.0 + 1e-12) + 1e-300;
    const double lb = std::max(0.0, s.hint_distance - (q - s.hint_query).norm());
    for (double step = 0.5 * r0;; step *= 2.0) {
      const double r = std::min(ub, lb + step);
      if (search(r)) {
        found = true;
        break;
      }
      if (r >= ub) break;
    }
  }
  if (!found) {
    double r = r0;
    for (int k = 0; k < 2200 && !search(r); ++k) r *= 2.0;
    if (s.ball.empty()) throw InvalidArgument("c2c: no nearest neighbour found (non-finite coordinates?)");
  }
  return closest_in_ball(tree.points(), q, s.ball);
}

/// Model neighbours of reference point p: within `radius`, or its k nearest (itself included,
/// ties by index). Returned in index order in s.ball.
void model_neighbours(const KdTree& tree, std::uint32_t p, const C2CParams& params, double r0, Scratch& s) {
  const PointsView pts = tree.points();
  const Vec3 c = pts[p];
  s.ball.clear();
  if (params.model_radius > 0) {
    tree.ball(c, params.model_radius, s.ball);
  } else {
    const std::size_t k = std::min<std::size_t>(params.model_neighbours, pts.size());
    double r = r0 * std::sqrt(static_cast<double>(k));
    for (int it = 0; it < 2200; ++it, r *= 2.0) {
      s.ball.clear();
      tree.ball(c, r, s.ball);
      if (s.ball.size() >= k) break;
    }
    s.ranked.clear();
    for (const std::uint32_t j : s.ball) s.ranked.emplace_back(detail::squared_distance(pts, j, c), j);
    std::nth_element(s.ranked.begin(), s.ranked.begin() + static_cast<std::ptrdiff_t>(k) - 1, s.ranked.end());
    s.ball.clear();
    for (std::size_t j = 0; j < k; ++j) s.ball.push_back(s.ranked[j].second);
  }
  std::sort(s.ball.begin(), s.ball.end());
}

/// |distance| from q to the PCA plane of the points s.ball (offsets taken from reference point
/// p so that UTM-sized coordinates lose nothing); NaN when there is no plane.
double plane_distance(PointsView pts, std::uint32_t p, const Vec3& q, const std::vector<std::uint32_t>& nb) {
  if (nb.size() < 3) return kNaN;
  const Vec3 origin = pts[p];
  Vec3 mean = Vec3::Zero();
  for (const std::uint32_t j : nb) mean += pts[j] - origin;
  mean /= static_cast<double>(nb.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const std::uint32_t j : nb) {
    const Vec3 v = pts[j] - origin - mean;
    cov += v * v.transpose();
  }
  cov /= static_cast<double>(nb.size());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(cov);
  const Eigen::Vector3d ev = solver.eigenvalues();  // ascending
  if (!(ev(2) > 0) || ev(1) <= 1e-12 * ev(2)) return kNaN;
  const Vec3 n = solver.eigenvectors().col(0);
  if (!n.allFinite()) return kNaN;
  return std::abs((q - origin - mean).dot(n));
}

void check_inputs(PointsView reference, PointsView queries, const char* query_name) {
  if (reference.empty()) throw InvalidArgument("the reference cloud is empty");
  if (reference.size() >= std::numeric_limits<std::uint32_t>::max())
    throw InvalidArgument("the reference cloud has too many points (" + std::to_string(reference.size()) + ")");
  detail::require_finite_points("reference", reference);
  detail::require_finite_points(query_name, queries);
}

}  // namespace

void nearest_neighbours(PointsView points, PointsView queries, std::vector<std::uint64_t>& index,
                        std::vector<double>& distance, const RunOptions& run) {
  check_inputs(points, queries, "queries");
  const KdTree tree(points);
  const double r0 = spacing_guess(points);
  index.assign(queries.size(), 0);
  distance.assign(queries.size(), kNaN);
  detail::parallel_blocks<Scratch>(queries.size(), run, [&](std::size_t begin, std::size_t end, Scratch& s) {
    s.have_hint = false;  // each block starts afresh: results never depend on the schedule
    for (std::size_t i = begin; i < end; ++i) {
      const Vec3 q = queries[i];
      const auto [sqd, j] = nearest(tree, q, r0, s);
      index[i] = j;
      distance[i] = std::sqrt(sqd);
      s.have_hint = true, s.hint_query = q, s.hint_nearest = j, s.hint_distance = distance[i];
    }
  });
}

C2CResult c2c(PointsView reference, PointsView compared, const C2CParams& params, const RunOptions& run) {
  check_inputs(reference, compared, "compared");
  if (params.model == LocalModel::kPlane) {
    if (!(params.model_radius >= 0) || !std::isfinite(params.model_radius))
      throw InvalidArgument("model radius must be >= 0 and finite, got " + std::to_string(params.model_radius));
    if (params.model_radius == 0 && params.model_neighbours < 3)
      throw InvalidArgument("a plane model needs at least 3 neighbours, got " +
                            std::to_string(params.model_neighbours));
  }
  const KdTree tree(reference);
  const double r0 = spacing_guess(reference);
  const std::size_t n = compared.size();
  C2CResult out;
  out.distance.assign(n, kNaN);
  out.nearest.assign(n, 0);
  out.model_distance.assign(n, kNaN);
  out.hf_distance.assign(n, kNaN);
  out.model_count.assign(n, 0);
  detail::parallel_blocks<Scratch>(n, run, [&](std::size_t begin, std::size_t end, Scratch& s) {
    s.have_hint = false;
    for (std::size_t i = begin; i < end; ++i) {
      const Vec3 q = compared[i];
      const auto [sqd, j] = nearest(tree, q, r0, s);
      const double d = std::sqrt(sqd);
      out.distance[i] = d;
      out.nearest[i] = j;
      s.have_hint = true, s.hint_query = q, s.hint_nearest = j, s.hint_distance = d;
      double hf = d;
      if (params.model == LocalModel::kPlane) {
        model_neighbours(tree, j, params, r0, s);
        out.model_count[i] = static_cast<std::uint32_t>(s.ball.size());
        const double m = plane_distance(reference, j, q, s.ball);
        out.model_distance[i] = m;
        if (!std::isnan(m)) hf = params.rule == ModelRule::kCloser ? std::min(d, m) : m;
      }
      out.hf_distance[i] = hf;
    }
  });
  return out;
}

}  // namespace m3c2
