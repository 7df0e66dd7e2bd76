// M3C2-EP (Winiwarter, Anders & Hoefle 2021): each point's covariance from its scanner's range
// and angle uncertainties, the compared epoch's alignment covariance, and the weighted centre of
// gravity of each cylinder (docs/algorithm.md#m3c2-ep).

#include "uncertainty/uncertainty.hpp"

#include <Eigen/Cholesky>

#include <cmath>

namespace m3c2::detail {

namespace {

using Mat3 = Eigen::Matrix3d;

/// The covariance of a point measured from a scanner at offset d = p - origin (polar range r,
/// horizontal angle yaw, zenith angle scan): J diag(s_r^2, s_yaw^2, s_scan^2) J^T with J the
/// Jacobian of (r sin(scan) cos(yaw), r sin(scan) sin(yaw), r cos(scan)). Its columns, written
/// with the offsets (no trigonometry): d / r, (-dy, dx, 0) and (dx dz / h, dy dz / h, -h) with
/// h = hypot(dx, dy).
Mat3 polar_covariance(const Vec3& d, const ScanPosition& sp) {
  const double r = d.norm(), h = std::hypot(d.x(), d.y());
  const double ppm = sp.sigma_range_ppm * 1e-6 * r;
  const double var_r = sp.sigma_range * sp.sigma_range + ppm * ppm;
  const Vec3 j_range = d / r;
  const Vec3 j_yaw(-d.y(), d.x(), 0.0);
  const Vec3 j_scan(d.x() * d.z() / h, d.y() * d.z() / h, -h);
  return var_r * j_range * j_range.transpose() + sp.sigma_yaw * sp.sigma_yaw * j_yaw * j_yaw.transpose() +
         sp.sigma_scan * sp.sigma_scan * j_scan * j_scan.transpose();
}

}  // namespace

UncertaintyModel::EpCloud UncertaintyModel::ep_cloud(int k) const {
  const bool moved = k == 1;
  return {moved, params_.ep_covariance == EpCovariance::kIndependent, moved ? compared_indexed() : reference_};
}

Mat3 UncertaintyModel::point_covariance(int k, std::uint32_t j, Vec3& original) const {
  const bool moved = k == 1;
  const auto& table = moved ? inputs_.compared.scan_positions : inputs_.reference.scan_positions;
  const auto& ids = moved ? inputs_.compared.scan_position : inputs_.reference.scan_position;
  original = moved ? original_compared(j) : reference_[j];
  const ScanPosition& sp = table[static_cast<std::size_t>(row_of_id_[k][ids[j]])];
  Mat3 cov = polar_covariance(original - Vec3(sp.origin[0], sp.origin[1], sp.origin[2]), sp);
  if (moved) cov = rotation_ * cov * rotation_.transpose();
  return cov;
}

/// The centre with scalar weights w_i = 1 / (n^T S_i n): the minimum-variance estimate of the
/// offset along n from points that each measure the surface along n (a cylinder's points lie at
/// different tangential positions, which matrix weights would mix into the offset). Its
/// covariance: sum w_i^2 S_i / (sum w_i)^2 (independent points) or the mean S_i; the alignment
/// part is J at the weighted mean of the original points (J is linear in the point).
CentreOfGravity UncertaintyModel::normal_weighted_centre(int k, const Vec3& core, const Vec3& normal,
                                                         std::span<const std::uint32_t> points) const {
  const auto [moved, independent, indexed] = ep_cloud(k);
  double weight_sum = 0.0;
  Vec3 weighted = Vec3::Zero(), d_weighted = Vec3::Zero(), d_sum = Vec3::Zero();
  Mat3 cov_w2 = Mat3::Zero(), mean_cov = Mat3::Zero(), dd_sum = Mat3::Zero();
  CentreOfGravity out;
  for (const std::uint32_t j : points) {
    Vec3 original;
    const Mat3 cov = point_covariance(k, j, original);
    const double along = normal.dot(cov * normal);
    if (!(along > 0.0) || !std::isfinite(along)) return out;
    const double w = 1.0 / along;
    weight_sum += w;
    weighted += w * (indexed[j] - core);
    cov_w2 += (w * w) * cov;
    mean_cov += cov;
    const Vec3 d = original - reduction_;
    d_weighted += w * d;
    d_sum += d;
    dd_sum += d * d.transpose();
  }
  if (!(weight_sum > 0.0)) return out;
  const double n = double(points.size());
  out.offset = weighted / weight_sum;
  out.covariance = independent ? Mat3(cov_w2 / (weight_sum * weight_sum)) : Mat3(mean_cov / n);
  if (moved && has_alignment_)
    out.covariance += independent ? alignment_at(d_weighted / weight_sum) : mean_alignment(d_sum / n, dd_sum / n);
  out.defined = out.covariance.allFinite();
  return out;
}

Mat3 UncertaintyModel::alignment_at(const Vec3& d) const {
  Eigen::Matrix<double, 3, 12> g = Eigen::Matrix<double, 3, 12>::Zero();
  for (int a = 0; a < 3; ++a) {
    g.block<1, 3>(a, 3 * a) = d.transpose();
    g(a, 9 + a) = 1.0;
  }
  return g * alignment_ * g.transpose();
}

Mat3 UncertaintyModel::mean_alignment(const Vec3& m, const Mat3& mm) const {
  // The mean of J_i C J_i^T over the points, from the moments of d (J is linear in d).
  Mat3 a = Mat3::Zero();
  for (int r = 0; r < 3; ++r)
    for (int s = 0; s < 3; ++s) {
      double v = alignment_(9 + r, 9 + s);
      for (int c = 0; c < 3; ++c) {
        v += alignment_(3 * r + c, 9 + s) * m(c) + alignment_(9 + r, 3 * s + c) * m(c);
        for (int e = 0; e < 3; ++e) v += alignment_(3 * r + c, 3 * s + e) * mm(c, e);
      }
      a(r, s) = v;
    }
  return a;
}

void UncertaintyModel::empirical(const Vec3& normal, std::span<const std::uint32_t> points2, std::size_t i, Result& r,
                                 Mat3& s1, Mat3& s2) const {
  // The unweighted mean's variance along n as eq. (1) estimates it (sigma^2 / n: the points'
  // measurement errors and the surface's sampling, whatever their source), and the alignment
  // covariance at the compared cylinder's mean (J is linear in the point).
  const Mat3 nn = normal * normal.transpose();
  s1 = (r.sigma1[i] * r.sigma1[i] / double(r.n1[i])) * nn;
  s2 = (r.sigma2[i] * r.sigma2[i] / double(r.n2[i])) * nn;
  if (!has_alignment_ || points2.empty()) return;
  Vec3 d = Vec3::Zero();
  for (const std::uint32_t j : points2) d += original_compared(j) - reduction_;
  s2 += alignment_at(d / double(points2.size()));
}

Vec3 UncertaintyModel::original_compared(std::uint32_t j) const {
  const Vec3 p = compared_[j];
  if (!inputs_.transform_applied) return p;
  return reduction_ + inverse_rotation_ * (p - reduction_ - translation_);
}

CentreOfGravity UncertaintyModel::centre_of_gravity(int k, const Vec3& core, const Vec3& normal,
                                                    std::span<const std::uint32_t> points) const {
  if (params_.ep_weights == EpWeights::kNormal) return normal_weighted_centre(k, core, normal, points);
  const auto [moved, independent, indexed] = ep_cloud(k);
  // Sums in the cylinder's key order: the same bits in any tile and thread.
  Mat3 weights = Mat3::Zero(), mean_cov = Mat3::Zero();
  Vec3 weighted = Vec3::Zero();
  // Alignment (compared cloud only): kIndependent needs sum W[a][r] d_k (27 sums), kMeanOfPoints
  // the first and second moments of d = p - reduction point.
  double wd[3][3][3] = {};
  Vec3 d_sum = Vec3::Zero();
  Mat3 dd_sum = Mat3::Zero();
  CentreOfGravity out;
  for (const std::uint32_t j : points) {
    Vec3 original;
    Mat3 cov = point_covariance(k, j, original);
    const Eigen::LLT<Mat3> llt(cov);
    if (llt.info() != Eigen::Success || !cov.allFinite()) return out;  // no weight: undefined
    const Mat3 w = llt.solve(Mat3::Identity());
    const Vec3 v = indexed[j] - core;
    weights += w;
    weighted += w * v;
    mean_cov += cov;
    if (moved && has_alignment_) {
      const Vec3 d = original - reduction_;
      if (independent) {
        for (int a = 0; a < 3; ++a)
          for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c) wd[a][r][c] += w(a, r) * d(c);
      } else {
        d_sum += d;
        dd_sum += d * d.transpose();
      }
    }
  }
  const Eigen::LLT<Mat3> normal_llt(weights);
  if (normal_llt.info() != Eigen::Success) return out;
  const Mat3 q = normal_llt.solve(Mat3::Identity());  // (sum W)^-1
  out.offset = q * weighted;
  const double n = double(points.size());
  out.covariance = independent ? q : Mat3(mean_cov / n);
  if (moved && has_alignment_) {
    // p' = R (p - red) + t + red is linear in x = (r11 .. r33, tx, ty, tz): dp'_a/dr_ac = d_c,
    // dp'_a/dt_a = 1, i.e. J = [I (x) d^T | I].
    Eigen::Matrix<double, 3, 12> g = Eigen::Matrix<double, 3, 12>::Zero();
    if (independent) {
      // The weighted mean's Jacobian: G = (sum W)^-1 sum W_i J_i; its translation block is I.
      Eigen::Matrix<double, 3, 9> s;
      for (int a = 0; a < 3; ++a)
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) s(a, 3 * r + c) = wd[a][r][c];
      g.leftCols<9>() = q * s;
      g.rightCols<3>() = Mat3::Identity();
      out.covariance += g * alignment_ * g.transpose();
    } else {
      out.covariance += mean_alignment(d_sum / n, dd_sum / n);
    }
  }
  out.defined = out.covariance.allFinite();
  return out;
}

}  // namespace m3c2::detail
