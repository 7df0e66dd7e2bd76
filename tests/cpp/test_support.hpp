#pragma once
// Shared fixtures for the GoogleTest suite: point clouds built from analytic surfaces or seeded
// random generators (fixed seeds only), brute-force oracles, and one tolerance helper.

#include <m3c2/m3c2.hpp>

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <span>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace m3c2::test {

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// Owning row-major xyz array with a PointsView onto it.
struct Cloud {
  std::vector<double> xyz;

  std::size_t size() const { return xyz.size() / 3; }
  PointsView view() const { return {xyz.data(), size()}; }
  Vec3 operator[](std::size_t i) const { return {xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]}; }
  void add(const Vec3& p) { add(p.x(), p.y(), p.z()); }
  void add(double x, double y, double z) {
    xyz.push_back(x);
    xyz.push_back(y);
    xyz.push_back(z);
  }
  void append(const Cloud& other) { xyz.insert(xyz.end(), other.xyz.begin(), other.xyz.end()); }
  Cloud translated(const Vec3& t) const {
    Cloud out;
    out.xyz.reserve(xyz.size());
    for (std::size_t i = 0; i < size(); ++i) out.add((*this)[i] + t);
    return out;
  }
  Cloud every_nth(std::size_t step, std::size_t first = 0) const {
    Cloud out;
    for (std::size_t i = first; i < size(); i += step) out.add((*this)[i]);
    return out;
  }
};

/// Two unit vectors u, v with (u, v, n) orthonormal and right-handed.
inline std::pair<Vec3, Vec3> orthonormal_basis(const Vec3& n_in) {
  const Vec3 n = n_in.normalized();
  const Vec3 helper = std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
  const Vec3 u = n.cross(helper).normalized();
  const Vec3 v = n.cross(u);
  return {u, v};
}

/// Square grid of (2 half + 1)^2 points in the plane through `origin` with normal `normal`:
/// origin + i spacing u + j spacing v for i, j in [-half, half], i major.
inline Cloud plane_grid(const Vec3& origin, const Vec3& normal, int half, double spacing) {
  const auto [u, v] = orthonormal_basis(normal);
  Cloud c;
  for (int i = -half; i <= half; ++i)
    for (int j = -half; j <= half; ++j) c.add(origin + (i * spacing) * u + (j * spacing) * v);
  return c;
}

/// Horizontal grid z = f(x, y) on [x0, x0 + (nx-1) dx] x [y0, y0 + (ny-1) dx], y major.
template <class F>
Cloud height_grid(double x0, double y0, int nx, int ny, double dx, F&& f) {
  Cloud c;
  c.xyz.reserve(3 * static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny));
  for (int r = 0; r < ny; ++r)
    for (int k = 0; k < nx; ++k) {
      const double x = x0 + k * dx, y = y0 + r * dx;
      c.add(x, y, f(x, y));
    }
  return c;
}

/// n points uniform in the box [lo, hi]^3.
inline Cloud random_box(std::uint64_t seed, std::size_t n, const Vec3& lo, const Vec3& hi) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  Cloud c;
  for (std::size_t i = 0; i < n; ++i) {
    const double a = u01(rng), b = u01(rng), d = u01(rng);
    c.add(lo.x() + a * (hi.x() - lo.x()), lo.y() + b * (hi.y() - lo.y()), lo.z() + d * (hi.z() - lo.z()));
  }
  return c;
}

/// Smooth rolling topography used by the rough random pairs.
inline double rough_height(double x, double y) {
  return 0.4 * std::sin(0.9 * x) * std::cos(0.6 * y) + 0.15 * std::sin(2.3 * x + 1.1 * y);
}

struct Pair {
  Cloud reference, compared, cores;
};

/// Two independent random samplings (n points each, xy uniform on [0, extent]^2) of the same
/// rough surface with Gaussian noise; the compared one is raised by `change`. Core points are
/// every 5th reference point.
inline Pair rough_pair(std::uint64_t seed, std::size_t n = 6000, double extent = 10.0, double noise = 0.03,
                       double change = 0.05) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, extent);
  std::normal_distribution<double> g(0.0, noise);
  Pair p;
  for (int cloud = 0; cloud < 2; ++cloud)
    for (std::size_t i = 0; i < n; ++i) {
      const double x = u(rng), y = u(rng);
      const double z = rough_height(x, y) + (cloud == 1 ? change : 0.0) + g(rng);
      (cloud == 0 ? p.reference : p.compared).add(x, y, z);
    }
  p.cores = p.reference.every_nth(5);
  return p;
}

/// numpy.isclose semantics (|a - b| <= atol + rtol |b|, NaN matches NaN); reports the first bad index.
inline ::testing::AssertionResult AllClose(std::span<const double> a, std::span<const double> b, double rtol,
                                           double atol) {
  if (a.size() != b.size()) return ::testing::AssertionFailure() << "size " << a.size() << " vs " << b.size();
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (std::isnan(a[i]) && std::isnan(b[i])) continue;
    if (!(std::abs(a[i] - b[i]) <= atol + rtol * std::abs(b[i])))
      return ::testing::AssertionFailure()
             << "index " << i << ": " << ::testing::PrintToString(a[i]) << " vs " << ::testing::PrintToString(b[i])
             << " (diff " << (a[i] - b[i]) << ", rtol " << rtol << ", atol " << atol << ")";
  }
  return ::testing::AssertionSuccess();
}

template <class T>
auto printable(T v) {
  if constexpr (std::is_enum_v<T>)
    return static_cast<long long>(static_cast<std::underlying_type_t<T>>(v));
  else if constexpr (std::is_integral_v<T>)
    return static_cast<long long>(v);
  else
    return ::testing::PrintToString(v);
}

/// Bit-for-bit equality of two arrays (memcmp), reporting the first differing index.
template <class T>
::testing::AssertionResult BitIdentical(const std::vector<T>& a, const std::vector<T>& b) {
  if (a.size() != b.size()) return ::testing::AssertionFailure() << "size " << a.size() << " vs " << b.size();
  for (std::size_t i = 0; i < a.size(); ++i)
    if (std::memcmp(&a[i], &b[i], sizeof(T)) != 0)
      return ::testing::AssertionFailure() << "index " << i << ": " << printable(a[i]) << " vs " << printable(b[i]);
  return ::testing::AssertionSuccess();
}

inline Vec3 normal_at(const std::vector<double>& normals, std::size_t i) {
  return {normals[3 * i], normals[3 * i + 1], normals[3 * i + 2]};
}

/// Brute-force cylinder membership with inclusive boundaries: squared distance to the axis
/// <= r^2 and t in [t_min, t_max], t = (p - c) . n.
inline std::uint32_t brute_cylinder_count(const Cloud& cloud, const Vec3& c, const Vec3& n, double radius, double t_min,
                                          double t_max) {
  std::uint32_t count = 0;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Vec3 d = cloud[i] - c;
    const double t = d.dot(n);
    const double r2 = (d - t * n).squaredNorm();
    if (r2 <= radius * radius && t >= t_min && t <= t_max) ++count;
  }
  return count;
}

/// Brute-force ball count with inclusive boundary: |p - c|^2 <= r^2.
inline std::uint32_t brute_ball_count(const Cloud& cloud, const Vec3& c, double radius) {
  std::uint32_t count = 0;
  for (std::size_t i = 0; i < cloud.size(); ++i)
    if ((cloud[i] - c).squaredNorm() <= radius * radius) ++count;
  return count;
}

inline RunOptions with_threads(int n) {
  RunOptions r;
  r.threads = n;
  return r;
}

/// Params with one normal scale and the given projection settings (kReference normals, +Z).
inline Params basic_params(double D, double d, double max_depth) {
  Params p;
  p.normal_diameters = {D};
  p.projection_diameter = d;
  p.max_depth = max_depth;
  return p;
}

}  // namespace m3c2::test
