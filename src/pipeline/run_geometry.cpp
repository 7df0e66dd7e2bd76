// Geometry and memory facts of a run that a caller needs before calling the engine: how far
// from a core point the engine can look (a tile's halo), how large a grid its integer cell
// indices allow, and what its spatial index costs per point (docs/architecture.md, docs/scaling.md).

#include <m3c2/m3c2.hpp>

#include "pipeline/core_point.hpp"

#include <algorithm>
#include <cmath>

namespace m3c2 {

double neighbourhood_reach(const Params& params) {
  // The normal sphere (radius D / 2, the largest D) or the cylinder (radius d / 2, half-length
  // max_depth, in any direction): sections 3.1.2 and 3.1.3.
  double sphere = 0.0;
  for (const double d : params.normal_diameters) sphere = std::max(sphere, d / 2);
  return std::max(sphere, std::hypot(params.projection_diameter / 2, params.max_depth));
}

double tile_halo(const Params& params) {
  // Extra points never change a result (membership is decided by the exact predicates), so a
  // generous hair of margin costs nothing and absorbs any rounding of the predicates.
  return neighbourhood_reach(params) * (1 + 1e-6) + 1e-6;
}

IndexMemory index_memory() { return {}; }

double memory_estimate(std::size_t n_reference, std::size_t n_compared, std::size_t n_core, const Params& params,
                       bool order_clouds_in_place) {
  const IndexMemory mem = index_memory();
  const double copy = order_clouds_in_place && detail::may_order_in_place(params) ? 0.0 : mem.copy_bytes_per_point;
  const auto cloud = [&](std::size_t n, bool reference) {
    const double moments = detail::moments_needed(params, reference) ? mem.moments_bytes_per_point : 0.0;
    return double(n) * (mem.bytes_per_point + copy + moments);
  };
  return (cloud(n_reference, true) + cloud(n_compared, false)) * mem.overhead +
         mem.bytes_per_core_point * double(n_core);
}

}  // namespace m3c2
