#include "kdtree.hpp"

#include <m3c2/errors.hpp>

#include <nanoflann.hpp>

#include <limits>
#include <string>

namespace m3c2::detail {
namespace {

struct CloudAdaptor {
  PointsView points;
  std::size_t kdtree_get_point_count() const { return points.size(); }
  double kdtree_get_pt(std::size_t i, std::size_t axis) const { return points.coord(i, int(axis)); }
  template <class Box>
  bool kdtree_get_bbox(Box&) const { return false; }
};

using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, CloudAdaptor>,
                                                 CloudAdaptor, 3, std::uint32_t>;

// nanoflann keeps only dist < r^2 and computes dist in its own order; it is asked for a slightly
// larger ball and the exact predicate of squared_distance() decides.
constexpr double kSearchInflation = 1.0 + 1e-9;

/// Collects candidate indices; the exact test runs afterwards on the original coordinates.
class CandidateSet {
 public:
  CandidateSet(double radius2, const PointsView& points, const Vec3& centre, double exact_r2,
               std::vector<std::uint32_t>& out)
      : radius2_(radius2), points_(points), centre_(centre), exact_r2_(exact_r2), out_(out) {}
  double worstDist() const { return radius2_; }
  bool full() const { return true; }
  bool addPoint(double dist, std::uint32_t index) {
    if (dist < radius2_ && squared_distance(points_, index, centre_) <= exact_r2_) out_.push_back(index);
    return true;
  }

 private:
  double radius2_;
  const PointsView& points_;
  const Vec3& centre_;
  double exact_r2_;
  std::vector<std::uint32_t>& out_;
};

}  // namespace

struct KdTree::Impl {
  explicit Impl(PointsView points) : adaptor{points}, tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(16)) {}
  CloudAdaptor adaptor;
  Tree tree;
};

KdTree::KdTree(PointsView points) : points_(points) {
  if (points.size() >= std::numeric_limits<std::uint32_t>::max())
    throw InvalidArgument("a cloud has " + std::to_string(points.size()) +
                          " points; one spatial index holds at most 4294967294 (use tiling)");
  if (!points.empty()) impl_ = std::make_unique<Impl>(points);
}

KdTree::~KdTree() = default;

void KdTree::ball(const Vec3& centre, double radius, std::vector<std::uint32_t>& out) const {
  if (!impl_) return;
  const double exact_r2 = radius * radius;
  const double search_r = radius * kSearchInflation + 1e-12;
  CandidateSet candidates(search_r * search_r, points_, centre, exact_r2, out);
  const double query[3] = {centre.x(), centre.y(), centre.z()};
  impl_->tree.findNeighbors(candidates, query, nanoflann::SearchParams(32, 0.0f, false));
}

}  // namespace m3c2::detail
