#include "pipeline/orientation.hpp"

#include <limits>

namespace m3c2::detail {

Vec3 orient(const Vec3& normal, const Vec3& core, const Orientation& orientation) {
  Vec3 reference(orientation.direction[0], orientation.direction[1], orientation.direction[2]);
  const auto& pts = orientation.points;
  if (!pts.empty()) {
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k + 2 < pts.size(); k += 3) {
      const Vec3 to(pts[k] - core.x(), pts[k + 1] - core.y(), pts[k + 2] - core.z());
      const double d2 = to.squaredNorm();
      if (d2 < best) best = d2, reference = to;
    }
    if (orientation.away) reference = -reference;
  }
  double dot = normal.dot(reference);
  if (dot == 0.0) dot = normal.z() != 0.0 ? normal.z() : normal.y() != 0.0 ? normal.y() : normal.x();
  return dot < 0.0 ? Vec3(-normal) : normal;
}

}  // namespace m3c2::detail
