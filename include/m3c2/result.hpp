#pragma once
// Per-core-point outcome of an M3C2 run. Index i of every vector refers to core point i.

#include <cstdint>
#include <string_view>
#include <vector>

namespace m3c2 {

/// Why a core point has no distance or no LOD. Numeric values are part of the file formats.
enum class PointStatus : std::uint8_t {
  kOk = 0,                  ///< distance and LOD computed
  kTooFewNormalPoints = 1,  ///< fewer neighbours than needed for the plane fit at every scale
  kDegenerateNormal = 2,    ///< collinear / coincident neighbours, or an unusable imposed normal
  kEmptyCylinder1 = 3,      ///< no reference point in the cylinder: no distance
  kEmptyCylinder2 = 4,      ///< no compared point in the cylinder: no distance
  kTooFewPointsForLod = 5,  ///< distance computed, but n1 or n2 < min_points: LOD NaN, not significant
};

std::string_view status_name(PointStatus s);

struct Result {
  std::vector<double> distance;           ///< i2 - i1 along the oriented normal; NaN if not computed
  std::vector<double> lod;                ///< level of detection at the confidence level; NaN if not computed
  std::vector<std::uint8_t> significant;  ///< 1 iff n1, n2 >= min_points and |distance| > lod
  /// Two-sided p-value of the test the LOD expresses (docs/algorithm.md, "p-values"): p < 1 -
  /// confidence exactly when significant is 1; NaN where the LOD is NaN (the status says why).
  std::vector<double> p_value;
  std::vector<std::uint32_t> n1, n2;   ///< points in each cylinder (0 where no cylinder was searched)
  std::vector<double> sigma1, sigma2;  ///< spread along the normal (std, or IQR / kIqrToSigma); NaN if undefined
  std::vector<double> i1, i2;          ///< central positions along the normal, from the core point
  std::vector<double> normal;          ///< 3 per core point, unit, oriented; NaN if not computed
  std::vector<double> normal_scale;    ///< D used (the chosen one with multi-scale)
  std::vector<double> roughness;       ///< sigma(D): spread of the normal neighbours about their plane
  std::vector<PointStatus> status;
  /// PM: each cloud's sigma on the normal; EP: sqrt(n^T S n) of each centre of gravity.
  /// Empty with Uncertainty::kEq1; NaN where not computed.
  std::vector<double> spread1, spread2;
  /// EP with UncertaintyInputs::covariances: each centre's 3x3 covariance, 9 per core point.
  std::vector<double> covariance1, covariance2;

  std::size_t size() const { return distance.size(); }
  void resize(std::size_t n);
};

/// Every per-core-point column of Result once, with its name, its values per core point (9: a
/// 3x3 matrix) and whether it is optional (empty unless some parameter asks for it):
/// `visit(name, column, width, optional)`. The binding builds its result dictionary from it and
/// the Python front end takes the schema from the binding (m3c2kit.engine.RESULT_FIELDS), so a new
/// column is added to the struct and here only.
template <class R, class Visitor>
void visit_result_fields(R& r, Visitor&& visit) {
  visit("status", r.status, 1, false);
  visit("distance", r.distance, 1, false);
  visit("lod", r.lod, 1, false);
  visit("significant", r.significant, 1, false);
  visit("p_value", r.p_value, 1, false);
  visit("n1", r.n1, 1, false);
  visit("n2", r.n2, 1, false);
  visit("sigma1", r.sigma1, 1, false);
  visit("sigma2", r.sigma2, 1, false);
  visit("i1", r.i1, 1, false);
  visit("i2", r.i2, 1, false);
  visit("normal", r.normal, 3, false);
  visit("normal_scale", r.normal_scale, 1, false);
  visit("roughness", r.roughness, 1, false);
  visit("spread1", r.spread1, 1, true);
  visit("spread2", r.spread2, 1, true);
  visit("covariance1", r.covariance1, 9, true);
  visit("covariance2", r.covariance2, 9, true);
}

/// Normals of one cloud at core points (section 3.1.2, 6.3).
struct NormalsResult {
  std::vector<double> normal;        ///< 3 per core point; NaN if not computed
  std::vector<double> normal_scale;  ///< D chosen
  std::vector<double> roughness;     ///< sigma(D)
  std::vector<std::uint32_t> count;  ///< neighbours at the chosen scale
  std::vector<PointStatus> status;   ///< kOk, kTooFewNormalPoints or kDegenerateNormal

  std::size_t size() const { return normal_scale.size(); }
  void resize(std::size_t n);
};

}  // namespace m3c2
