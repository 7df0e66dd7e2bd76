"""The report's section for runs with a per-point uncertainty model (``--uncertainty pm|ep``,
docs/algorithm.md §6.5; issue 16): which model replaced eq. (1), the inputs it was given (the
user's value, else the default the run used) and the distribution of the propagated spreads
(columns spread1, spread2) and of the LOD they make."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["UncertaintySection", "uncertainty_section", "MODELS"]

#: --uncertainty value -> (the model's name, what it replaces eq. (1)'s spread with).
MODELS = {
    "pm": ("M3C2-PM (precision maps; James, Robson & Smith 2017)",
           "each point's precisions (sx, sy, sz) projected on the normal, scaled per cloud; "
           "LOD = z (sqrt(spread1^2 + spread2^2) + registration error)"),
    "ep": ("M3C2-EP (error propagation; Winiwarter et al. 2021)",
           "each point's covariance propagated from its scanner's range and angular errors and the "
           "alignment's covariance to the weighted centres of gravity of the cylinder"),
}

#: The inputs of each model, in the table's order: (parameter name, label).
INPUTS = {
    "pm": (("precision_fields", "precision fields (sx, sy, sz)"),
           ("precision_scales", "precision scales (reference, compared)"),
           ("precision_rule", "precision rule")),
    "ep": (("scan_positions", "scan positions (reference[, compared])"),
           ("scan_position_field", "scan-position id field"),
           ("transform", "transformation tfM (compared epoch)"),
           ("transform_applied", "transformation already applied"),
           ("alignment_covariance", "alignment covariance Cxx (12 x 12)"),
           ("reduction_point", "reduction point"),
           ("ep_covariance", "covariance of a centre of gravity"),
           ("ep_weights", "weights of the centres of gravity"),
           ("ep_lod", "level of detection")),
}

#: What an EP input that was not given means (the run used the identity, none, the origin).
_EP_ABSENT = {"transform": "none (identity)", "alignment_covariance": "none (no alignment uncertainty)",
              "reduction_point": "0, 0, 0", "scan_positions": "none"}

QUANTILES = (0.05, 0.5, 0.95)


@dataclass
class UncertaintySection:
    model: str
    description: str
    inputs: list         # (label, value)
    distribution: list   # (quantity, count with a value, min, 5 %, median, 95 %, max), as text


def _value(params: dict, name: str, kind: str):
    from ...settings import by_name

    value = params.get(name)
    if value is None:
        if kind == "ep" and name in _EP_ABSENT:
            return _EP_ABSENT[name]
        value = by_name()[name].default_for(params.get("compat"))
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (list, tuple, np.ndarray)):
        return ", ".join(f"{float(v):.6g}" if isinstance(v, (float, np.floating)) else str(v) for v in value)
    return "none" if value is None else str(value)


def _row(name: str, values) -> tuple:
    a = np.asarray(values, dtype=float) if values is not None else np.empty(0)
    a = a[np.isfinite(a)]
    if a.size == 0:
        return (name, "0") + ("n/a",) * (2 + len(QUANTILES))
    q = np.quantile(a, QUANTILES)
    return (name, str(a.size), f"{a.min():.6g}", *(f"{v:.6g}" for v in q), f"{a.max():.6g}")


def uncertainty_section(result) -> UncertaintySection | None:
    """The section of a run with --uncertainty pm or ep; None for eq. (1) runs."""
    kind = (result.params or {}).get("uncertainty", "eq1")
    if kind not in MODELS:
        return None
    model, description = MODELS[kind]
    inputs = [(label, _value(result.params, name, kind)) for name, label in INPUTS[kind]]
    inputs.append(("registration error", _value(result.params, "registration_error", kind)))
    distribution = [_row("spread1 (reference)", getattr(result, "spread1", None)),
                     _row("spread2 (compared)", getattr(result, "spread2", None)),
                     _row("LOD", result.lod)]
    return UncertaintySection(model, description, inputs, distribution)
