"""The groups `m3c2 compare`'s parameters are shown in, in this order: CloudCompare qM3C2's dialog
tabs (scales, normals, statistics, uncertainty, output; CANUPO's vegetation removal beside them),
then how the run is made. One owner for three places that show them: `m3c2 compare --help`
(argparse groups), docs/cli.md's table (the `group` column) and QGIS's compare dialog
(parameters.json's `group`: the dialog's labels start with it, in this order).
tests/python/settings/test_groups.py holds every compare row to exactly one group."""
from __future__ import annotations

__all__ = ["GROUPS", "group_of", "group_rank"]

#: (title, the parameter table's rows in it), the groups in the order a dialog shows them (within a
#: group, the rows keep the table's order).
GROUPS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("Scales", ("normal_scale", "projection_scale", "max_depth", "core_spacing", "depth_search", "first_pass_depth",
                "positive_search_only")),
    ("Normals", ("normal_source", "orient", "scale_selection", "min_points_normal", "min_points_multiscale",
                 "normal_subsample")),
    ("Statistics", ("confidence", "lod", "min_points", "median", "median_lod", "variance", "t_statistic", "bootstrap",
                    "seed", "fdr", "fdr_method")),
    ("Uncertainty", ("registration_error", "error_model", "uncertainty", "precision_rule", "precision_scales",
                     "precision_fields", "ep_covariance", "ep_lod", "ep_weights", "scan_positions",
                     "scan_position_field", "transform", "transform_applied", "alignment_covariance",
                     "reduction_point")),
    ("Vegetation", ("classifier", "keep")),
    ("Output", ("position", "field_names", "float64", "all_fields")),
    ("Run", ("threads", "compat")),
)

_OF = {name: title for title, names in GROUPS for name in names}
_RANK = {name: rank for rank, (_, names) in enumerate(GROUPS) for name in names}


def group_of(name: str) -> str | None:
    """The title of the group row `name` is shown in; None for a row `m3c2 compare` does not take."""
    return _OF.get(name)


def group_rank(name: str) -> int:
    """Where row `name`'s group comes in the dialogs (rows of no group last); within a group, rows
    keep the parameter table's order."""
    return _RANK.get(name, len(GROUPS))
