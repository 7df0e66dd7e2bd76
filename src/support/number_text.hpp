#pragma once

#include <sstream>
#include <string>

namespace m3c2::detail {

/// `v` in a message with `digits` significant digits (std::to_string writes fixed notation: 1e300
/// as its 301 digits, 1e-20 as 0.000000).
inline std::string number_text(double v, int digits) {
  std::ostringstream s;
  s.precision(digits);
  s << v;
  return s.str();
}

}  // namespace m3c2::detail
