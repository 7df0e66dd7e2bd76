#pragma once
// Non-owning views of float64 point arrays: the engine never copies the caller's coordinates.

#include <Eigen/Core>

#include <cstddef>

namespace m3c2 {

using Vec3 = Eigen::Vector3d;

/// View of N points stored row-major (x0, y0, z0, x1, ...), as a C-contiguous numpy (N, 3)
/// float64 array is. The memory must outlive every object built on the view.
class PointsView {
 public:
  PointsView() = default;
  PointsView(const double* xyz, std::size_t n) : xyz_(xyz), n_(n) {}

  std::size_t size() const { return n_; }
  bool empty() const { return n_ == 0; }
  const double* data() const { return xyz_; }
  Vec3 operator[](std::size_t i) const { return {xyz_[3 * i], xyz_[3 * i + 1], xyz_[3 * i + 2]}; }
  double coord(std::size_t i, int axis) const { return xyz_[3 * i + axis]; }

 private:
  const double* xyz_ = nullptr;
  std::size_t n_ = 0;
};

}  // namespace m3c2
