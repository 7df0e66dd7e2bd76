#pragma once
// Level of detection: eq. (1), the Welch t of eq. (2) and the critical values (section 3.3).

#include "uncertainty/p_value.hpp"

#include <m3c2/params.hpp>

#include <cstdint>

namespace m3c2::detail {

/// Two-tailed standard normal critical value: 1.959963984540054 at 0.95.
double z_critical(double confidence);

/// Two-tailed Student t critical value with (possibly fractional) degrees of freedom.
double t_critical(double confidence, double dof);

/// Welch-Satterthwaite degrees of freedom, eq. (2) of section 3.3, from the standard errors of
/// the two centres (sigma_k / sqrt(n_k) for the mean). A `known_variance` (the error model's
/// sigma_c^2) joins the numerator's sum as a component with infinite degrees of freedom, which
/// add nothing to the denominator (Satterthwaite 1946; docs/algorithm.md, "Spatially correlated errors").
/// The n may be effective (Kish's, TAM3C2's weighted sides): real, > 1.
double welch_dof(double se1, double n1, double se2, double n2, double known_variance = 0.0);

/// The critical value eq. (1) multiplies, as params.lod says: z (kZ, kBootstrap), Welch's t
/// (kT), or the paper's rule (kAuto): t when n1 or n2 < 30, else z; the median with the
/// Maritz-Jarrett standard error always takes z under kAuto (its calibration, docs/validation.md).
/// `z` is z_critical(params.confidence), computed once per run.
double critical_value(const Params& params, double z, double se1, std::uint32_t n1, double se2, std::uint32_t n2);

/// The law critical_value() takes its quantile from: the normal, or Student's t with eq. (2)'s
/// degrees of freedom (the p-value's law, p_value.hpp).
TestLaw critical_law(const Params& params, double se1, std::uint32_t n1, double se2, std::uint32_t n2);

/// Eq. (1)'s LOD (lod_parametric with critical_value) and its test, for p_value.hpp's decide().
LodTest parametric_test(const Params& params, double z, double se1, std::uint32_t n1, double se2, std::uint32_t n2);

/// The bootstrap LOD (Appendix B), z (sqrt(sigma_b^2 + correlated_variance) + reg) with sigma_b
/// the bootstrap's sd of the distance, and its test: the normal-theory bootstrap test whose
/// statistic is |d| over the same scale (docs/algorithm.md, "p-values").
LodTest bootstrap_test(const Params& params, double z, double bootstrap_sigma);

/// Eq. (1): critical * (sqrt(se1^2 + se2^2 + correlated_variance) + reg), se_k the standard error
/// of centre k, correlated_variance params.correlated_variance (0 in the paper's eq. (1)).
double lod_parametric(double critical, double se1, double se2, double registration_error, double correlated_variance);

/// The scale eq. (1)'s critical value multiplies: sqrt(se1^2 + se2^2 + correlated_variance) + reg.
double lod_scale(double se1, double se2, double registration_error, double correlated_variance);

}  // namespace m3c2::detail
