// The shared observation model's instantiations of the filter and smoother (series/kalman_filter.hpp;
// include/m3c2/kalman.hpp, KalmanObservation::kShared): the state [d, d' (, d''), b].

#include "series/kalman_filter.hpp"

namespace m3c2::detail::kalman {

KalmanSmoothed smooth_shared(const KalmanParams& p, const KalmanBlock& b, const RunOptions& run) {
  return p.model == KalmanModel::kAcceleration ? smooth_k<3, 4>(p, b, run) : smooth_k<2, 3>(p, b, run);
}

double likelihood_shared(const KalmanParams& p, const KalmanBlock& b, const RunOptions& run) {
  return p.model == KalmanModel::kAcceleration ? likelihood_k<3, 4>(p, b, run) : likelihood_k<2, 3>(p, b, run);
}

}  // namespace m3c2::detail::kalman
