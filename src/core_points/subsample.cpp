#include <m3c2/m3c2.hpp>

#include "index/distance.hpp"
#include "pipeline/validation.hpp"

#include <cmath>
#include <cstdint>
#include <unordered_map>

namespace m3c2 {
namespace {

struct CellKey {
  std::int64_t x, y, z;
  bool operator==(const CellKey&) const = default;
};
struct CellHash {
  std::size_t operator()(const CellKey& k) const {
    return std::size_t(k.x * 73856093LL ^ k.y * 19349663LL ^ k.z * 83492791LL);
  }
};

}  // namespace

std::vector<std::uint64_t> subsample_min_spacing(PointsView points, double min_spacing) {
  detail::require_positive("min_spacing", min_spacing);
  detail::require_finite_points("points", points);
  detail::require_cell_count("min_spacing", min_spacing, points);
  // Greedy in input order over a hash grid of cell = spacing: a candidate only needs the kept
  // points of its 27 surrounding cells. Serial, so the result is one and the same everywhere.
  std::unordered_map<CellKey, std::vector<std::uint64_t>, CellHash> kept_in_cell;
  std::vector<std::uint64_t> kept;
  const Vec3 origin = points.empty() ? Vec3::Zero() : points[0];
  const double s2 = min_spacing * min_spacing;
  // A hair larger than the spacing: rounding of (p - origin) / cell can then never put two points
  // closer than the spacing more than one cell apart.
  const double cell = min_spacing * (1.0 + 1e-9);
  for (std::uint64_t i = 0; i < points.size(); ++i) {
    const Vec3 p = points[i];
    const CellKey key{std::int64_t(std::floor((p.x() - origin.x()) / cell)),
                      std::int64_t(std::floor((p.y() - origin.y()) / cell)),
                      std::int64_t(std::floor((p.z() - origin.z()) / cell))};
    bool too_close = false;
    for (std::int64_t dx = -1; dx <= 1 && !too_close; ++dx)
      for (std::int64_t dy = -1; dy <= 1 && !too_close; ++dy)
        for (std::int64_t dz = -1; dz <= 1 && !too_close; ++dz) {
          const auto it = kept_in_cell.find({key.x + dx, key.y + dy, key.z + dz});
          if (it == kept_in_cell.end()) continue;
          for (const std::uint64_t j : it->second)
            if (detail::squared_distance(points, j, p) < s2) {
              too_close = true;
              break;
            }
        }
    if (too_close) continue;
    kept.push_back(i);
    kept_in_cell[key].push_back(i);
  }
  return kept;
}

}  // namespace m3c2
