#pragma once
// The projection cylinder (section 3.1.3).

#include <m3c2/points_view.hpp>

namespace m3c2::detail {

/// The projection cylinder of section 3.1.3: axis through `core` along the unit `normal`,
/// radius `radius` (d / 2), axial offsets t in [t_min, t_max]. Both boundaries are inclusive:
/// p is inside iff |v - t n|^2 <= radius^2 and t_min <= t <= t_max, with v = p - core and
/// t = v . n, computed in that order in float64 (docs/algorithm.md#boundaries).
struct Cylinder {
  Vec3 core;
  Vec3 normal;
  double radius = 0.0;
  double t_min = 0.0;
  double t_max = 0.0;
};

}  // namespace m3c2::detail
