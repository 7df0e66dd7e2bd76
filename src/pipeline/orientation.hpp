#pragma once
// Orientation of normals (section 3.1.2).

#include <m3c2/params.hpp>
#include <m3c2/points_view.hpp>

namespace m3c2::detail {

/// Flips `normal` so that it points towards the closest orientation point (the paper's scanner
/// positions; the lowest index wins a tie) or, when there are none, along the preferred
/// direction. When the normal is orthogonal to that reference the sign is made deterministic:
/// the first non-zero component among (z, y, x) is made positive.
Vec3 orient(const Vec3& normal, const Vec3& core, const Orientation& orientation);

}  // namespace m3c2::detail
