#pragma once
// Cloud-to-cloud baselines of section 3.4 (Lague et al. 2013, Fig. 4): the closest-point
// distance C2C and the closest point corrected by a local model, C2C_HF. They exist to be
// compared with M3C2 (validation/fig4.py, docs/analysis.md), not as change measurements.

#include <m3c2/points_view.hpp>
#include <m3c2/run_options.hpp>

#include <cstdint>
#include <vector>

namespace m3c2 {

/// Local surface model fitted around the closest reference point (CloudCompare's "local model").
enum class LocalModel : std::uint8_t {
  kNone,   ///< plain closest point (C2C)
  kPlane,  ///< least-squares plane (PCA) of the closest point's reference neighbours (C2C_HF)
};

/// How C2C_HF combines the model distance with the closest-point distance.
enum class ModelRule : std::uint8_t {
  kCloser,     ///< min(closest-point distance, model distance): CloudCompare >= 2.5 ("best estimation")
  kModelOnly,  ///< the model distance whenever a model exists: CloudCompare 2.3, the paper's version
};

struct C2CParams {
  LocalModel model = LocalModel::kNone;
  /// > 0: the model's neighbours are the reference points within this radius (inclusive) of the
  /// closest reference point. 0: the `model_neighbours` nearest reference points of the closest
  /// point, itself included (ties by index), CloudCompare's kNN mode.
  double model_radius = 0.0;
  std::uint32_t model_neighbours = 6;  ///< CloudCompare's default kNN for local models
  ModelRule rule = ModelRule::kCloser;
};

struct C2CResult {
  std::vector<double> distance;            ///< C2C: Euclidean distance to the closest reference point
  std::vector<std::uint64_t> nearest;      ///< index of that point (the lowest index among equidistant ones)
  std::vector<double> model_distance;      ///< |distance to the local plane|; NaN where no model was fitted
  std::vector<double> hf_distance;         ///< C2C_HF by `rule`; the C2C distance where there is no model
  std::vector<std::uint32_t> model_count;  ///< neighbours used for the model (0 without a model)

  std::size_t size() const { return distance.size(); }
};

/// C2C (and C2C_HF with params.model = kPlane) from each compared point to the reference cloud.
/// Exact nearest neighbour (float64, ties to the lowest index), multi-threaded, bit-identical
/// for any thread count. The plane is the PCA plane of the model neighbours (centroid, eigenvector
/// of the smallest eigenvalue of their covariance); with fewer than 3 neighbours or collinear ones
/// (lambda2 <= 1e-12 lambda1) there is no model: model_distance is NaN and hf_distance = distance.
/// Throws InvalidArgument for an empty reference, non-finite coordinates or bad model parameters.
C2CResult c2c(PointsView reference, PointsView compared, const C2CParams& params = {}, const RunOptions& run = {});

/// Index of the nearest point of `points` to each query (ties to the lowest index), and the
/// distance: the building block of c2c, exposed for tests and analysis.
void nearest_neighbours(PointsView points, PointsView queries, std::vector<std::uint64_t>& index,
                        std::vector<double>& distance, const RunOptions& run = {});

}  // namespace m3c2
