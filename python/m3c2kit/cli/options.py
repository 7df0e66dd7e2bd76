"""Every option that more than one subcommand takes, declared once (issue 32): its flags, its type
and range, and one help text.

Two sources, one rule each:
- a parameter of the parameter table (m3c2kit.settings.table: `--threads`, `--min-points`,
  `--variance`...) is declared from its row by `add_table_option`, so that its help and range are
  the table's in every subcommand that takes it; a value out of range is the UsageError that
  m3c2kit.settings.resolve gives for the same value in a --params file;
- an option of the command line alone (`-q`, `--core FILE`, `--plot`...) is an `Option` of
  `OPTIONS` below, added by `add(parser, name)`.

A shared help says what the option means. Its default is the command's: a value default is shown
by the help formatter (m3c2kit.cli.parser.HelpFormatter); one the command derives (every reference
point, d) is the `default_text` the command passes, appended as "(default: ...)".
tests/python/cli/test_cli_options.py walks every parser so that the next duplicate fails."""
from __future__ import annotations

import argparse
import functools
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from ..base.errors import UsageError
from ..settings import by_name, parameters_of
from ..settings.groups import GROUPS, group_of, group_rank
from ..settings.table import Parameter
from .integers import SEED_MAX, integer

__all__ = ["Option", "OPTIONS", "add", "add_table_option", "add_table_options", "argument_sections",
           "add_verbosity_options", "add_progress_option", "table_type", "table_help"]


@dataclass(frozen=True)
class Option:
    """A command-line option shared by several subcommands. `type` None (and no `row`): an on/off flag."""

    flags: tuple[str, ...]
    help: str
    type: Callable | None = str
    metavar: str | None = None
    row: str | None = None  # the parameter table's row whose type and range it takes: the same quantity


OPTIONS: dict[str, Option] = {
    # Talking (m3c2kit.cli.parser.phases_for)
    "quiet": Option(("-q", "--quiet"), "no progress bar or summary (warnings and errors still go to stderr)", None),
    "verbose": Option(("--verbose",), "also print the parameters the run used", None),
    "progress": Option(("--progress",), "show the progress bars on stderr even when it is not a terminal "
                                        "(default: only on a terminal); --progress json: one JSON line per update "
                                        "instead, {\"phase\", \"done\", \"total\", \"percent\"} (the run's "
                                        "percent, monotone), for a program that follows the run", None),
    # Inputs
    "core": Option(("--core",), "core points file", Path),
    "core_normals": Option(("--core-normals",), "with --normal-source core: file of nx,ny,nz per core point "
                                                "(default: the core file's normal fields)", Path),
    "ignore_crs": Option(("--ignore-crs",), "compare clouds whose CRS or units differ, or of which only one has "
                                            "a CRS, or in degrees (default: an error naming them)", None),
    "dask_scheduler": Option(("--dask-scheduler",), "run the work as tasks on this Dask distributed scheduler (the "
                                                    "same output bit for bit); every worker must be able to read the "
                                                    "inputs and write beside the output (docs/scaling.md)",
                             metavar="ADDRESS"),
    # The analysis commands' (docs/analysis.md): the cylinder and the normals of their self-comparisons
    # are the table's parameters, with defaults each command derives from d.
    "cloud_core_spacing": Option(("--core-spacing",), "core points = the cloud --core defaults to, subsampled to "
                                                      "this minimum spacing", row="core_spacing"),
    "derived_normal_scale": Option(("--normal-scale",), "D, the normal scale: a DIAMETER", row="normal_scale"),
    "derived_max_depth": Option(("--max-depth",), "half-length of the cylinder along the normal, on each side",
                                row="max_depth"),
    "fixed_orient": Option(("--orient",), "normal orientation, as m3c2 compare's --orient"),
    "fit_range": Option(("--fit-range",), "the scales used in the fits, MIN:MAX", metavar="MIN:MAX"),
    "sample_seed": Option(("--seed",), "seed of the command's random draws: the same seed, the same result",
                          integer(0, SEED_MAX)),
    # Outputs
    "plot": Option(("--plot",), "also draw the command's figure in this file (its extension chooses the format: "
                                "PNG, PDF, SVG...)", Path, metavar="FILE"),
}


def add(parser, name: str, *, default=None, default_text: str | None = None,
        required: bool = False) -> argparse.Action:
    """Adds OPTIONS[name] to `parser` (or an argument group); `default_text`: the command's default
    in words, when it is no value the formatter could show."""
    option = OPTIONS[name]
    text = option.help if default_text is None else f"{option.help} (default: {default_text})"
    if option.row is None and option.type is None:
        return parser.add_argument(*option.flags, action="store_true", help=text)
    kind = table_type(by_name()[option.row]) if option.row is not None else option.type
    return parser.add_argument(*option.flags, type=kind, default=default, required=required, metavar=option.metavar,
                               help=text)


def table_type(param: Parameter) -> Callable[[str], object]:
    """argparse's type for a table row: its `cli_type` (argparse names it in "invalid int value"),
    then the row's range (`kind`), whose UsageError is the one resolve() gives a --params file's
    value. The value is returned as read: resolve() converts it with the others (a series step's,
    which has no resolve step, as its row converted it). One per row."""
    return _row_type(param.name)


@functools.cache
def _row_type(name: str) -> Callable[[str], object]:
    param = by_name()[name]

    def parse(text: str):
        value = param.cli_type(text)
        checked = param.kind(param.flag, value)
        return checked if param.scope == "series" else value  # a series step has no resolve() to convert it

    parse.__name__ = param.cli_type.__name__
    return parse


def table_help(param: Parameter, compat: bool) -> str:
    """The row's help and default; with the --compat cloudcompare default only where the command
    takes --compat."""
    return param.help_text() if compat else f"{param.help} ({param.default_clause()})"


def add_table_option(parser, name: str | Parameter, *, filled: bool = False, compat: bool = False,
                     required: bool = False) -> argparse.Action:
    """The table's row `name` as an option of `parser` (or a group). Its default is None (not given)
    where the command resolves its settings through the table (m3c2kit.settings.resolve: --params
    values and --compat defaults can tell what the user said); `filled`: the table's default, for
    the commands that pass the value on as it is."""
    param = by_name()[name] if isinstance(name, str) else name
    default = param.default_for() if filled else None
    text = table_help(param, compat)
    if param.cli_type is None:
        return parser.add_argument(param.flag, dest=param.name, action="store_true",
                                   default=bool(default) if filled else None, help=text)
    return parser.add_argument(param.flag, dest=param.name, type=table_type(param), choices=param.choices,
                               metavar=param.metavar, default=default, required=required, help=text)


def add_table_options(parser, command: str, groups: dict | None = None, sections: dict | None = None) -> None:
    """One option per parameter of `command` in the parameter table (m3c2kit.settings.table), in
    `groups[name]` (an argument group of its own), else in `sections[group_of(name)]`
    (argument_sections), else in `parser`. Every default is None (not given): the table fills it
    in, so --params values and --compat defaults can tell what the user said."""
    params = parameters_of(command)
    compat = any(p.name == "compat" for p in params)
    if sections:
        params = sorted(params, key=lambda p: group_rank(p.name))
    for param in params:
        target = (groups or {}).get(param.name) or (sections or {}).get(group_of(param.name)) or parser
        add_table_option(target, param, compat=compat)


def argument_sections(parser) -> dict:
    """The parameter groups of m3c2kit.settings.groups as argument groups of `parser`, in their
    order: {title: group}."""
    return {title: parser.add_argument_group(title) for title, _ in GROUPS}


def step_options(p, command: str, groups: dict | None = None) -> None:
    """The parameter table's rows of the step `command` (a series step, settings/series_rows.py;
    pbm3c2, settings/pbm3c2_rows.py) as options of `p`, in argument groups by section (`groups`).
    A row that acts only with another option (its `needs`) is None when not given, so that the
    step can refuse it where it would change nothing; the others carry their default."""
    from ..settings.table import parameters_of
    titles = {}
    for row in parameters_of(command):
        title = (groups or {}).get(row.section)
        target = p if title is None else titles.setdefault(title, p.add_argument_group(title))
        add_table_option(target, row, filled=not row.needs)


def single_normal_scale(value, what: str) -> float | None:
    """--normal-scale of a command that takes one D (`what`: its use, for the message), or None."""
    if value is None:
        return None
    from ..settings.parsers import normal_scales
    scales = normal_scales(value, "--normal-scale")
    if len(scales) != 1:
        raise UsageError(f"--normal-scale: {what} takes one D, got {value!r}")
    return scales[0]


def add_verbosity_options(parser) -> None:
    """-q/--quiet or --verbose, not both."""
    talk = parser.add_mutually_exclusive_group()
    add(talk, "quiet")
    add(talk, "verbose")


def add_progress_option(parser) -> None:
    """--progress (bars), or --progress json (m3c2kit.base.phases: one JSON line per update)."""
    option = OPTIONS["progress"]
    parser.add_argument(*option.flags, nargs="?", const="bars", choices=("bars", "json"), help=option.help)
