"""Every `m3c2` subcommand: its one-line help and the module and function that build its parser.

`m3c2 --help` (and an unknown command) lists the subcommands from here alone, importing none of
their modules; a run builds the parser of its own subcommand only (cli/main.py, make_parser),
so `m3c2 info` never imports the series or the classifier (issue 45: `--help` imported every
subcommand's modules, numpy among them). Each builder takes its subcommand's help from here."""
from __future__ import annotations

__all__ = ["COMMANDS", "summary"]

#: name -> (module of m3c2kit.cli, the function that adds its parser(s) to the subparsers, help).
#: One function may add several (analysis_parsers: roughness ... suggest); the order is the help's.
COMMANDS = {
    "compare": ("compare", "compare_parser", "M3C2 distances between two clouds"),
    "normals": ("commands", "normals_parser", "normals at the most planar scale, with roughness (section 6.3)"),
    "subsample": ("commands", "subsample_parser", "subsample to a minimum spacing (core points)"),
    "info": ("commands", "info_parser", "point count, bounds, CRS and fields of a file"),
    "convert": ("commands", "convert_parser", "copy a point-cloud file into another format, every field kept"),
    "roughness": ("analysis", "analysis_parsers",
                  "roughness sigma(D) vs scale and the self-affine fit (section 5.1, Fig. 6a)"),
    "calibrate": ("analysis", "analysis_parsers",
                  "LOD95 calibration on subsampled copies of one cloud (5.2.1-5.2.2, Figs. 8-9)"),
    "c2c": ("analysis", "analysis_parsers", "closest-point baselines C2C and C2C_HF (section 3.4)"),
    "simplify": ("analysis", "analysis_parsers", "self-comparison: local averaging or outlier removal (section 6.3)"),
    "suggest": ("analysis", "analysis_parsers", "suggest D, d and the max depth for a pair of clouds"),
    "classify": ("classify", "classify_parsers", "CANUPO multi-scale dimensionality classification (Brodu & Lague 2012)"),
    "series": ("series", "series_parsers", "M3C2 time series: a store of many epochs, 4D objects-by-change"),
    "variogram": ("variogram", "variogram_parser",
                  "the variogram of the distance over stable core points: the error model of --error-model"),
    "register": ("register", "register_parser",
                 "point-to-plane ICP on stable areas: the transform, its covariance and reg of eq. (1) for compare"),
    "pbm3c2": ("pbm3c2", "pbm3c2_parser",
               "PB-M3C2: the change between paired planar segments, with its LOD (Zahs et al. 2022)"),
    "aggregate": ("aggregate", "aggregate_parser",
                  "per region: mean change, volume and area of significant change, with intervals that account for "
                  "spatially correlated errors"),
}


def summary(name: str) -> str:
    """The subcommand's one-line help."""
    return COMMANDS[name][2]
