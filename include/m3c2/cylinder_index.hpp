#pragma once
// One cloud's points in cylinders of any diameter and length along given axes (the cylinder of
// section 3.1.3, step 2), from one index: how the data-quality diagnosis of empty cylinders
// (m3c2kit.quality) asks a cloud whether a cylinder reaches it at any depth, and whether a wider
// one does, without building the index again for each question.

#include <m3c2/points_view.hpp>
#include <m3c2/run_options.hpp>

#include <cstdint>
#include <memory>
#include <vector>

namespace m3c2 {

/// Per core point: the points in its cylinder, and the mean and the sample standard deviation of
/// their offsets along the axis from the core point, summed as compute() sums a cylinder's with
/// the default statistics (NaN mean when empty, NaN sigma below 2 points). A core point whose
/// axis is zero or not finite gets count 0.
struct CylinderStatistics {
  std::vector<std::uint32_t> count;
  std::vector<double> mean, sigma;
};

/// An index of `cloud` (read in place: it must outlive this) on the grid of compute() with
/// projection scale `smallest_diameter` and no normal scales, so that a cylinder of that
/// diameter gives compute()'s bits; wider ones give the same points (their sums may differ in
/// the last bits from compute()'s own index for that diameter). statistics() is const and may
/// run concurrently. Throws InvalidArgument when a coordinate is not finite or beyond the grid.
class CylinderIndex {
 public:
  CylinderIndex(PointsView cloud, double smallest_diameter, const RunOptions& run = {});
  ~CylinderIndex();
  CylinderIndex(CylinderIndex&&) noexcept;
  CylinderIndex& operator=(CylinderIndex&&) noexcept;

  /// The cylinders of `diameter` (>= the index's smallest) and half-length `half_length` at each
  /// core point along normals[3 i .. 3 i + 2] (rescaled to unit length).
  CylinderStatistics statistics(PointsView core_points, const std::vector<double>& normals, double diameter,
                                double half_length, const RunOptions& run = {}) const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace m3c2
