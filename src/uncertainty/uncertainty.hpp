#pragma once
// The per-point uncertainty models of include/m3c2/uncertainty.hpp inside compute(): prepared
// once per run (inputs checked, EP's transformed compared cloud), then applied per core point
// to the points of its two cylinders (docs/algorithm.md §6.5).

#include <m3c2/params.hpp>
#include <m3c2/points_view.hpp>
#include <m3c2/result.hpp>
#include <m3c2/run_options.hpp>
#include <m3c2/uncertainty.hpp>

#include <span>
#include <vector>

namespace m3c2::detail {

/// M3C2-PM's sigma of one cylinder (James et al. 2017, CloudCompare's qM3C2): scale ||(n . s)||
/// of the point nearest the centre of gravity of `points` (kNearest), or scale sqrt(mean ||n . s||^2)
/// (kAllPoints). `points`: indices into `cloud` and `precision` (3 per point).
double precision_sigma(PointsView cloud, std::span<const double> precision, std::span<const std::uint32_t> points,
                       const Vec3& normal, double scale, PrecisionRule rule);

/// M3C2-EP's weighted centre of gravity of one cylinder and its covariance.
struct CentreOfGravity {
  Vec3 offset = Vec3::Zero();  ///< centre - core point
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  bool defined = false;  ///< false: a point's covariance is singular (no weight)
};

class UncertaintyModel {
 public:
  /// Checks `inputs` against the clouds and params (InvalidArgument naming the input); for EP
  /// with the transformation not yet applied, builds the transformed compared cloud.
  UncertaintyModel(const Params& params, const UncertaintyInputs& inputs, PointsView reference, PointsView compared,
                   const RunOptions& run);

  /// The compared cloud to index and project: EP's transformed copy, or `compared` itself.
  PointsView compared_indexed() const {
    return transformed_.empty() ? compared_ : PointsView(transformed_.data(), compared_.size());
  }

  /// LOD, spreads and significance of core point i (PM), and its distance and i1, i2 (EP, from
  /// the weighted centres), from the indices of the points of its two cylinders.
  void measure(const Vec3& core, const Vec3& normal, std::span<const std::uint32_t> points1,
               std::span<const std::uint32_t> points2, std::size_t i, Result& r) const;

  /// EP: the weighted centre of gravity of `points` of cloud k (0 reference, 1 compared).
  CentreOfGravity centre_of_gravity(int k, const Vec3& core, const Vec3& normal,
                                    std::span<const std::uint32_t> points) const;

 private:
  /// What both EP centres of gravity need of cloud k (0 reference, 1 compared), set up once.
  struct EpCloud {
    bool moved;          ///< the compared cloud: its points were transformed by tfM
    bool independent;    ///< EpCovariance::kIndependent (else the mean of the points' covariances)
    PointsView indexed;  ///< the points as indexed and projected
  };
  EpCloud ep_cloud(int k) const;
  /// Point j of cloud k: its covariance from its scan position, in the indexed frame (rotated
  /// with the compared cloud), and in `original` its position before the transformation.
  Eigen::Matrix3d point_covariance(int k, std::uint32_t j, Vec3& original) const;
  Vec3 original_compared(std::uint32_t j) const;
  CentreOfGravity normal_weighted_centre(int k, const Vec3& core, const Vec3& normal,
                                         std::span<const std::uint32_t> points) const;
  /// J(d) C J(d)^T: the alignment covariance of a point at d = p - reduction point.
  Eigen::Matrix3d alignment_at(const Vec3& d) const;
  /// The mean of J_i C J_i^T over points whose d has mean m and second moment mm.
  Eigen::Matrix3d mean_alignment(const Vec3& m, const Eigen::Matrix3d& mm) const;
  /// EpCovariance::kEmpirical's covariances of core point i (from eq. (1)'s spreads in r).
  void empirical(const Vec3& normal, std::span<const std::uint32_t> points2, std::size_t i, Result& r,
                 Eigen::Matrix3d& s1, Eigen::Matrix3d& s2) const;

  const Params& params_;
  const UncertaintyInputs& inputs_;
  PointsView reference_, compared_;
  std::vector<double> transformed_;
  std::vector<std::int32_t> row_of_id_[2];  // scan-position id -> row of the cloud's table
  Eigen::Matrix3d rotation_, inverse_rotation_;
  Vec3 translation_, reduction_;
  Eigen::Matrix<double, 12, 12> alignment_;
  bool has_alignment_ = false;
  double z_ = 0.0, chi2_ = 0.0;
};

/// Validates the uncertainty parameters of `params` (part of validate_params).
void validate_uncertainty_params(const Params& params);

}  // namespace m3c2::detail
