#pragma once
// The engine's few questions to OpenMP, answered for a serial build too (CMake option
// M3C2_USE_OPENMP=OFF, or no OpenMP found): one thread, number 0. Results never depend on the
// thread count (parallel_for.hpp), so a serial build gives the same bits; CI checks it
// (scripts/check-serial.sh).

#if defined(_OPENMP)
#include <omp.h>
#endif

namespace m3c2::detail {

/// Threads a parallel region may use when the caller asks for 0 (all).
inline int max_threads() {
#if defined(_OPENMP)
  return omp_get_max_threads();
#else
  return 1;
#endif
}

/// This thread's number in the enclosing parallel region (0 outside one, and in a serial build).
inline int thread_num() {
#if defined(_OPENMP)
  return omp_get_thread_num();
#else
  return 0;
#endif
}

/// Threads of the enclosing parallel region (1 outside one, and in a serial build).
inline int team_size() {
#if defined(_OPENMP)
  return omp_get_num_threads();
#else
  return 1;
#endif
}

}  // namespace m3c2::detail
