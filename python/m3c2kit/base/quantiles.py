"""The two-sided normal critical value, for the Python steps that state a band or an interval at a
confidence level (the Kalman band, TAM3C2's LOD, the aggregates' intervals): one place, so every
such band uses the same z. The engine's LODs take theirs from Boost.Math (src/uncertainty/
confidence.cpp, z_critical); both are the exact quantile to within rounding."""
from __future__ import annotations

from statistics import NormalDist


def z_critical(confidence: float) -> float:
    """z with P(|Z| <= z) = confidence: 1.959963984540054 at 0.95. Where 0.5 + confidence / 2
    rounds to 1 (confidence 0.9999999999999999: a StatisticsError reached the user), from the lower
    tail, (1 - confidence) / 2, which keeps its digits; the upper tail elsewhere (the same bits as before)."""
    upper = 0.5 + 0.5 * float(confidence)
    if upper < 1.0:
        return NormalDist().inv_cdf(upper)
    return -NormalDist().inv_cdf(0.5 * (1.0 - float(confidence)))
