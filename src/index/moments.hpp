#pragma once
// Moments of a point set (count, mean, co-moment matrix) and their exact pairwise merge, the
// update of Chan, Golub & LeVeque (1979). Normals (section 3.1.2) need only the co-moment.

#include <m3c2/points_view.hpp>

#include <array>

namespace m3c2::detail {

struct Moments {
  double count = 0.0;
  Vec3 mean = Vec3::Zero();
  std::array<double, 6> comoment{};  ///< xx, xy, xz, yy, yz, zz of sum (v - mean)(v - mean)^T
};

/// acc <- moments of the union. Merging with an empty set copies, so that a set's moments do
/// not depend on how many empty sets were merged on the way (the octree relies on it).
inline void merge_into(Moments& acc, const Moments& b) {
  if (b.count == 0.0) return;
  if (acc.count == 0.0) {
    acc = b;
    return;
  }
  const double n = acc.count + b.count;
  const Vec3 d = b.mean - acc.mean;
  const double w = acc.count * b.count / n;
  auto& m = acc.comoment;
  const auto& mb = b.comoment;
  m[0] += mb[0] + w * d.x() * d.x(), m[1] += mb[1] + w * d.x() * d.y(), m[2] += mb[2] + w * d.x() * d.z();
  m[3] += mb[3] + w * d.y() * d.y(), m[4] += mb[4] + w * d.y() * d.z(), m[5] += mb[5] + w * d.z() * d.z();
  acc.mean += d * (b.count / n);
  acc.count = n;
}

/// Moments of the points xyz[slots[j]] - origin, j in [0, n) (ascending slots), in two passes
/// (mean, then co-moment about it) in that order. The only place a set of points becomes moments.
inline Moments two_pass_moments(const double* xyz, const std::uint32_t* slots, std::uint32_t n, const Vec3& origin) {
  Moments m;
  if (n == 0) return m;
  Vec3 sum = Vec3::Zero();
  for (std::uint32_t j = 0; j < n; ++j) {
    const double* p = xyz + 3 * std::size_t(slots[j]);
    sum += Vec3(p[0] - origin.x(), p[1] - origin.y(), p[2] - origin.z());
  }
  m.count = double(n);
  m.mean = sum / m.count;
  auto& c = m.comoment;
  for (std::uint32_t j = 0; j < n; ++j) {
    const double* p = xyz + 3 * std::size_t(slots[j]);
    const Vec3 v = Vec3(p[0] - origin.x(), p[1] - origin.y(), p[2] - origin.z()) - m.mean;
    c[0] += v.x() * v.x(), c[1] += v.x() * v.y(), c[2] += v.x() * v.z();
    c[3] += v.y() * v.y(), c[4] += v.y() * v.z(), c[5] += v.z() * v.z();
  }
  return m;
}

/// two_pass_moments() of the one point p - origin, without its loops: count 1, mean
/// 0 + (p - origin) (the sum's first addition, kept for the sign of zero) divided by 1, co-moment
/// zero (the offset from the mean is exactly 0 for finite p). The same bits.
inline Moments one_point_moments(const double* p, const Vec3& origin) {
  Moments m;
  m.count = 1.0;
  m.mean = (Vec3::Zero() + Vec3(p[0] - origin.x(), p[1] - origin.y(), p[2] - origin.z())) / m.count;
  const Vec3 v = Vec3(p[0] - origin.x(), p[1] - origin.y(), p[2] - origin.z()) - m.mean;
  auto& c = m.comoment;
  c[0] += v.x() * v.x(), c[1] += v.x() * v.y(), c[2] += v.x() * v.z();
  c[3] += v.y() * v.y(), c[4] += v.y() * v.z(), c[5] += v.z() * v.z();
  return m;
}

}  // namespace m3c2::detail
