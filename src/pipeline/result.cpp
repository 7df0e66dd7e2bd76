#include <m3c2/result.hpp>

#include <limits>

namespace m3c2 {

std::string_view status_name(PointStatus s) {
  switch (s) {
    case PointStatus::kOk: return "ok";
    case PointStatus::kTooFewNormalPoints: return "too_few_normal_points";
    case PointStatus::kDegenerateNormal: return "degenerate_normal";
    case PointStatus::kEmptyCylinder1: return "empty_cylinder_reference";
    case PointStatus::kEmptyCylinder2: return "empty_cylinder_compared";
    case PointStatus::kTooFewPointsForLod: return "too_few_points_for_lod";
  }
  return "unknown";
}

void Result::resize(std::size_t n) {
  constexpr double nan = std::numeric_limits<double>::quiet_NaN();
  for (auto* v : {&distance, &lod, &p_value, &sigma1, &sigma2, &i1, &i2, &normal_scale, &roughness}) v->assign(n, nan);
  normal.assign(3 * n, nan);
  significant.assign(n, 0);
  n1.assign(n, 0);
  n2.assign(n, 0);
  status.assign(n, PointStatus::kTooFewNormalPoints);
}

void NormalsResult::resize(std::size_t n) {
  constexpr double nan = std::numeric_limits<double>::quiet_NaN();
  normal.assign(3 * n, nan);
  normal_scale.assign(n, nan);
  roughness.assign(n, nan);
  count.assign(n, 0);
  status.assign(n, PointStatus::kTooFewNormalPoints);
}

}  // namespace m3c2
