#pragma once
// Error channels (docs/algorithm.md#errors): caller mistakes throw InvalidArgument naming the
// value; a run stopped by the progress callback throws Cancelled. Per-core-point failures are
// never exceptions: they are NaN plus a PointStatus in the Result.

#include <stdexcept>
#include <string>

namespace m3c2 {

struct InvalidArgument : std::invalid_argument {
  using std::invalid_argument::invalid_argument;
};

struct Cancelled : std::runtime_error {
  Cancelled() : std::runtime_error("computation cancelled") {}
};

}  // namespace m3c2
