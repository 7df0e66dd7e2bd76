// Setting up the per-point uncertainty of a run (inputs checked once, EP's transformed compared
// cloud) and the per-core-point LOD of M3C2-PM and M3C2-EP (docs/algorithm.md §6.5).

#include "uncertainty/uncertainty.hpp"

#include "support/parallel_for.hpp"
#include "uncertainty/confidence.hpp"

#include <m3c2/errors.hpp>

#include <boost/math/distributions/chi_squared.hpp>

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace m3c2::detail {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
const char* const kCloudName[2] = {"reference cloud", "compared cloud"};

void check_precision(const CloudUncertainty& c, PointsView cloud, const char* name) {
  if (c.precision.size() != 3 * cloud.size())
    throw InvalidArgument(std::string(name) + ": uncertainty pm needs 3 precisions (sx, sy, sz) per point (" +
                          std::to_string(3 * cloud.size()) + " values), got " + std::to_string(c.precision.size()));
  for (std::size_t i = 0; i < c.precision.size(); ++i)
    if (!(c.precision[i] >= 0.0) || !std::isfinite(c.precision[i]))
      throw InvalidArgument(std::string(name) + ": precision " + "xyz"[i % 3] + " of point " + std::to_string(i / 3) +
                            " must be finite and >= 0, got " + std::to_string(c.precision[i]));
}

/// The row of each scan-position id of `c`'s table; throws naming the cloud on a bad table or id.
std::vector<std::int32_t> scan_rows(const CloudUncertainty& c, PointsView cloud, const char* name) {
  if (c.scan_positions.empty())
    throw InvalidArgument(std::string(name) + ": uncertainty ep needs a scan-position table (scan_positions)");
  if (c.scan_position.size() != cloud.size())
    throw InvalidArgument(std::string(name) + ": uncertainty ep needs a scan-position id per point (" +
                          std::to_string(cloud.size()) + "), got " + std::to_string(c.scan_position.size()));
  std::uint32_t largest = 0;
  for (const ScanPosition& sp : c.scan_positions) {
    const std::string what = std::string(name) + ": scan position " + std::to_string(sp.id);
    for (const double v : sp.origin)
      if (!std::isfinite(v)) throw InvalidArgument(what + " has a non-finite origin");
    for (const double v : {sp.sigma_range, sp.sigma_range_ppm, sp.sigma_scan, sp.sigma_yaw})
      if (!(v >= 0.0) || !std::isfinite(v)) throw InvalidArgument(what + " has a sigma that is not finite and >= 0");
    if (!(sp.sigma_range > 0.0 || sp.sigma_range_ppm > 0.0) || !(sp.sigma_scan > 0.0) || !(sp.sigma_yaw > 0.0))
      throw InvalidArgument(what +
                            " needs sigma_range (or sigma_range_ppm), sigma_scan and sigma_yaw > 0 "
                            "(a zero sigma leaves its points' covariance singular)");
    if (sp.id > (1u << 24)) throw InvalidArgument(what + ": ids must be <= 2^24");
    largest = std::max(largest, sp.id);
  }
  std::vector<std::int32_t> rows(std::size_t(largest) + 1, -1);
  for (std::size_t r = 0; r < c.scan_positions.size(); ++r) {
    auto& slot = rows[c.scan_positions[r].id];
    if (slot >= 0)
      throw InvalidArgument(std::string(name) + ": scan position " + std::to_string(c.scan_positions[r].id) +
                            " is listed twice");
    slot = static_cast<std::int32_t>(r);
  }
  for (std::size_t i = 0; i < c.scan_position.size(); ++i) {
    const std::uint32_t id = c.scan_position[i];
    if (id >= rows.size() || rows[id] < 0)
      throw InvalidArgument(std::string(name) + ": point " + std::to_string(i) + " has scan position id " +
                            std::to_string(id) + ", which the scan-position table does not list");
  }
  return rows;
}

}  // namespace

void validate_uncertainty_params(const Params& p) {
  if (p.uncertainty == Uncertainty::kEq1) return;
  const char* name = p.uncertainty == Uncertainty::kPrecisionMaps ? "pm" : "ep";
  // PM's precision maps and EP's alignment covariance already model the correlated error the
  // variogram measures: adding it would count it twice.
  if (p.correlated_variance != 0.0)
    throw InvalidArgument(
        std::string("uncertainty ") + name +
        " models correlated errors itself: an error model (correlated_variance) applies to eq. (1) only");
  // Its LOD has no n-dependent statistic: z applies (Lod::kAuto's rule gives z too); the bootstrap
  // and Welch's t are eq. (1)'s.
  if (p.lod == Lod::kBootstrap)
    throw InvalidArgument(std::string("uncertainty ") + name + " replaces eq. (1): it cannot be bootstrapped");
  if (p.lod == Lod::kT)
    throw InvalidArgument(std::string("uncertainty ") + name + " has no Welch t (eq. (2) is eq. (1)'s)");
  if (p.uncertainty == Uncertainty::kPrecisionMaps) {
    for (const double s : {p.precision_scale1, p.precision_scale2})
      if (!(s >= 0.0) || !std::isfinite(s))
        throw InvalidArgument("precision scales must be finite and >= 0, got " + std::to_string(s));
    return;
  }
  if (p.registration_error != 0.0)
    throw InvalidArgument(
        "uncertainty ep takes the registration error from the alignment covariance: "
        "registration_error must be 0");
  if (p.statistic != Statistic::kMean)
    throw InvalidArgument("uncertainty ep measures from weighted centres of gravity: statistic must be mean");
}

UncertaintyModel::UncertaintyModel(const Params& params, const UncertaintyInputs& inputs, PointsView reference,
                                   PointsView compared, const RunOptions& run)
    : params_(params), inputs_(inputs), reference_(reference), compared_(compared) {
  z_ = z_critical(params.confidence);
  if (params.uncertainty == Uncertainty::kPrecisionMaps) {
    check_precision(inputs.reference, reference, kCloudName[0]);
    check_precision(inputs.compared, compared, kCloudName[1]);
  }
  if (params.uncertainty != Uncertainty::kErrorPropagation) return;
  row_of_id_[0] = scan_rows(inputs.reference, reference, kCloudName[0]);
  row_of_id_[1] = scan_rows(inputs.compared, compared, kCloudName[1]);
  for (const double v : inputs.transform)
    if (!std::isfinite(v)) throw InvalidArgument("the transformation (tfM) has a non-finite value");
  for (const double v : inputs.reduction_point)
    if (!std::isfinite(v)) throw InvalidArgument("the reduction point has a non-finite coordinate");
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) rotation_(a, b) = inputs.transform[4 * a + b];
    translation_(a) = inputs.transform[4 * a + 3];
    reduction_(a) = inputs.reduction_point[a];
  }
  const Eigen::FullPivLU<Eigen::Matrix3d> lu(rotation_);
  if (!lu.isInvertible()) throw InvalidArgument("the transformation's 3x3 part (tfM) is not invertible");
  inverse_rotation_ = lu.inverse();
  const auto& c = inputs.alignment_covariance;
  if (!c.empty()) {
    if (c.size() != 144)
      throw InvalidArgument("the alignment covariance (Cxx) must be 12x12 (144 values), got " +
                            std::to_string(c.size()));
    for (int a = 0; a < 12; ++a)
      for (int b = 0; b < 12; ++b) {
        alignment_(a, b) = c[12 * a + b];
        if (!std::isfinite(alignment_(a, b)))
          throw InvalidArgument("the alignment covariance (Cxx) has a non-finite value");
        if (c[12 * a + b] != c[12 * b + a]) throw InvalidArgument("the alignment covariance (Cxx) is not symmetric");
      }
    has_alignment_ = alignment_.cwiseAbs().maxCoeff() > 0.0;
  } else {
    alignment_.setZero();
  }
  const boost::math::chi_squared chi2(3.0);
  chi2_ = boost::math::quantile(chi2, params.confidence);
  if (!inputs.transform_applied) {
    // The compared epoch moved onto the reference (py4dgeo's M3C2EP does the same): the index,
    // the normals and the cylinders see p' = R (p - red) + t + red.
    transformed_.resize(3 * compared.size());
    RunOptions quiet = run;  // set-up, not core points: no progress reported
    quiet.progress = nullptr;
    parallel_blocks<int>(
        compared.size(), quiet,
        [&](std::size_t begin, std::size_t end, int&) {
          for (std::size_t j = begin; j < end; ++j) {
            const Vec3 p = reduction_ + rotation_ * (compared[j] - reduction_) + translation_;
            for (int a = 0; a < 3; ++a) transformed_[3 * j + a] = p(a);
          }
        },
        4096);
  }
}

void UncertaintyModel::measure(const Vec3& core, const Vec3& normal, std::span<const std::uint32_t> points1,
                               std::span<const std::uint32_t> points2, std::size_t i, Result& r) const {
  if (params_.uncertainty == Uncertainty::kPrecisionMaps) {
    // qM3C2: sigma_k = scale_k ||n . s|| and LOD = z (sqrt(sigma1^2 + sigma2^2) + reg), with no
    // 1/n (a precision map's error is shared by the cylinder's points, James et al. 2017 eq. 2).
    const double s1 = precision_sigma(reference_, inputs_.reference.precision, points1, normal,
                                      params_.precision_scale1, params_.precision_rule);
    const double s2 = precision_sigma(compared_, inputs_.compared.precision, points2, normal, params_.precision_scale2,
                                      params_.precision_rule);
    r.spread1[i] = s1, r.spread2[i] = s2;
    LodTest test;  // a normal test of d over the same scale (docs/algorithm.md, "p-values")
    test.scale = std::sqrt(s1 * s1 + s2 * s2) + params_.registration_error;
    test.lod = r.lod[i] = z_ * test.scale;
    decide(test, 1.0 - params_.confidence, i, r);
    r.status[i] = PointStatus::kOk;
    return;
  }
  CentreOfGravity a, b;
  LodTest test;  // EP's LOD and the test it expresses (set with the LOD below)
  if (params_.ep_covariance == EpCovariance::kEmpirical) {
    // eq. (1)'s distance and spreads (already in r), the alignment propagated (docs/algorithm.md §6.5)
    a.offset = r.i1[i] * normal, b.offset = r.i2[i] * normal;
    empirical(normal, points2, i, r, a.covariance, b.covariance);
    a.defined = b.defined = std::isfinite(r.sigma1[i]) && std::isfinite(r.sigma2[i]);
  } else {
    a = centre_of_gravity(0, core, normal, points1), b = centre_of_gravity(1, core, normal, points2);
  }
  if (!a.defined && params_.ep_covariance == EpCovariance::kEmpirical) {
    r.lod[i] = kNaN;
    r.status[i] = PointStatus::kTooFewPointsForLod;
    return;
  }
  if (a.defined && b.defined) {
    r.i1[i] = normal.dot(a.offset), r.i2[i] = normal.dot(b.offset);
    r.distance[i] = r.i2[i] - r.i1[i];  // our sign: compared - reference along the normal
    const Eigen::Matrix3d sum = a.covariance + b.covariance;
    r.spread1[i] = std::sqrt(normal.dot(a.covariance * normal));
    r.spread2[i] = std::sqrt(normal.dot(b.covariance * normal));
    if (inputs_.covariances)
      for (int e = 0; e < 9; ++e)
        r.covariance1[9 * i + e] = a.covariance(e / 3, e % 3), r.covariance2[9 * i + e] = b.covariance(e / 3, e % 3);
    if (params_.ep_lod == EpLod::kProjected) {
      test.scale = std::sqrt(normal.dot(sum * normal));  // the distance's standard error
      r.lod[i] = z_ * test.scale;
    } else {
      // d^2 n^T S^-1 n > chi2(3, confidence): T = |d| / scale with scale = (n^T S^-1 n)^-1/2
      const Eigen::LLT<Eigen::Matrix3d> llt(sum);
      const double w = llt.info() == Eigen::Success ? normal.dot(llt.solve(normal)) : kNaN;
      r.lod[i] = std::sqrt(chi2_ / w);
      test.scale = 1.0 / std::sqrt(w);
      test.law = {TestLaw::Kind::kChiSquared, 3.0};
    }
  } else {
    r.distance[i] = r.i1[i] = r.i2[i] = kNaN;
  }
  const std::uint32_t fewest = std::max(params_.min_points, 1u);
  if (!std::isfinite(r.lod[i]) || points1.size() < fewest || points2.size() < fewest) {
    r.lod[i] = kNaN;
    r.status[i] = PointStatus::kTooFewPointsForLod;
    return;
  }
  test.lod = r.lod[i];
  decide(test, 1.0 - params_.confidence, i, r);
  r.status[i] = PointStatus::kOk;
}

}  // namespace m3c2::detail
