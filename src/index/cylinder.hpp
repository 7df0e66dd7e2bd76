#pragma once
// The projection cylinder (section 3.1.3).

#include <m3c2/points_view.hpp>

#include <array>
#include <cmath>

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

/// Whether the axis-aligned box [lo, hi] may hold a point of `cyl` (unit normal): false only
/// when none of its points can be inside, with a slack far above rounding, so a pruned box never
/// holds a point the per-point test would keep (that test alone decides membership). With b the
/// box's centre and e its half-extents, relative to the core point: the box's offsets along the
/// axis lie in b . n +- sum e_a |n_a|; its distance from the axis is at least |w| - sum e_a |u_a|,
/// w = b - (b . n) n the centre's radial offset and u = w / |w| (a point b + s of the box has
/// radial offset w + P s, P the projection off the axis, and u . (w + P s) = |w| + u . s).
inline bool box_may_meet(const std::array<double, 3>& lo, const std::array<double, 3>& hi, const Cylinder& cyl) {
  double b[3], e[3], t = 0.0, spread = 0.0, size = cyl.radius + std::abs(cyl.t_min) + std::abs(cyl.t_max);
  for (int a = 0; a < 3; ++a) {
    const double l = lo[a] - cyl.core(a), h = hi[a] - cyl.core(a);
    b[a] = 0.5 * (l + h), e[a] = 0.5 * (h - l);
    t += b[a] * cyl.normal(a), spread += e[a] * std::abs(cyl.normal(a));
    size += std::abs(b[a]) + e[a];
  }
  const double slack = 1e-9 * size;
  if (t + spread < cyl.t_min - slack || t - spread > cyl.t_max + slack) return false;
  double w[3], norm2 = 0.0;
  for (int a = 0; a < 3; ++a) w[a] = b[a] - t * cyl.normal(a), norm2 += w[a] * w[a];
  const double norm = std::sqrt(norm2);
  if (!(norm > 0.0)) return true;
  double reach = 0.0;
  for (int a = 0; a < 3; ++a) reach += e[a] * std::abs(w[a]) / norm;
  return norm - reach <= cyl.radius + slack;
}

}  // namespace m3c2::detail
