#pragma once
// Level of detection: eq. (1), the Welch t of eq. (2) and the critical values (section 3.3).

#include <m3c2/params.hpp>

#include <cstdint>

namespace m3c2::detail {

/// Two-tailed standard normal critical value: 1.959963984540054 at 0.95.
double z_critical(double confidence);

/// Two-tailed Student t critical value with (possibly fractional) degrees of freedom.
double t_critical(double confidence, double dof);

/// Welch-Satterthwaite degrees of freedom, eq. (2) of section 3.3, from the standard errors of
/// the two centres (sigma_k / sqrt(n_k) for the mean).
double welch_dof(double se1, std::uint32_t n1, double se2, std::uint32_t n2);

/// The critical value eq. (1) multiplies, as params.lod says: z (kZ, kBootstrap), Welch's t
/// (kT), or the paper's rule (kAuto): t when n1 or n2 < 30, else z; the median with the
/// Maritz-Jarrett standard error always takes z under kAuto (its calibration, docs/validation.md).
/// `z` is z_critical(params.confidence), computed once per run.
double critical_value(const Params& params, double z, double se1, std::uint32_t n1, double se2, std::uint32_t n2);

/// Eq. (1): critical * (sqrt(se1^2 + se2^2) + reg), se_k the standard error of centre k.
double lod_parametric(double critical, double se1, double se2, double registration_error);

}  // namespace m3c2::detail
