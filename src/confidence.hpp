#pragma once
// Level of detection: eq. (1), the Welch t of eq. (2) and the critical values (section 3.3).

#include <m3c2/params.hpp>

#include <cstdint>

namespace m3c2::detail {

/// Two-tailed standard normal critical value: 1.959963984540054 at 0.95.
double z_critical(double confidence);

/// Two-tailed Student t critical value with (possibly fractional) degrees of freedom.
double t_critical(double confidence, double dof);

/// Welch-Satterthwaite degrees of freedom, eq. (2) of section 3.3.
double welch_dof(double sigma1, std::uint32_t n1, double sigma2, std::uint32_t n2);

/// The critical value eq. (1) multiplies: z, or Welch's t when requested and n1 or n2 < 30.
/// `z` is z_critical(params.confidence), computed once per run.
double critical_value(const Params& params, double z, double sigma1, std::uint32_t n1,
                      double sigma2, std::uint32_t n2);

/// Eq. (1): critical * (sqrt(sigma1^2 / n1 + sigma2^2 / n2) + reg).
double lod_parametric(double critical, double sigma1, std::uint32_t n1, double sigma2,
                      std::uint32_t n2, double registration_error);

}  // namespace m3c2::detail
