#pragma once
// M3C2 time series (docs/series.md): one reference cloud and its core points compared with many
// epochs. The reference's index and the core points' normals are computed once; each epoch then
// costs its own index and the cylinders. Every epoch's result equals compute(reference, epoch,
// core_points, params) bit for bit: both run the steps of src/pipeline/core_point.hpp.

#include <m3c2/params.hpp>
#include <m3c2/points_view.hpp>
#include <m3c2/result.hpp>
#include <m3c2/run_options.hpp>

#include <memory>
#include <vector>

namespace m3c2 {

/// A reference prepared for comparing epochs: its index, the core points (copied) and their
/// oriented normals (section 3.1.2). The normals come from the reference, the vertical or the
/// caller (NormalSource kReference, kHorizontal, kVertical, kCorePoints): kCompared and kMean
/// depend on each epoch and are refused (InvalidArgument). The reference's coordinates are read
/// in place and must outlive the Comparison. compare() is const and may run concurrently.
class Comparison {
 public:
  Comparison(PointsView reference, PointsView core_points, const Params& params, const RunOptions& run = {},
             const std::vector<double>& core_normals = {});
  ~Comparison();
  Comparison(Comparison&&) noexcept;
  Comparison& operator=(Comparison&&) noexcept;

  /// The M3C2 result of one epoch: compute(reference, compared, core_points, params) bit for bit.
  Result compare(PointsView compared, const RunOptions& run = {}) const;

  /// The core points' normals, their scale, roughness and status (count is 0: not kept).
  NormalsResult normals() const;

  std::size_t size() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace m3c2
