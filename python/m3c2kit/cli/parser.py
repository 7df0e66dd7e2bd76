"""The command line's argument parser class, shared by every subcommand's parsers (m3c2kit.cli):
argparse's own usage errors become UsageError (exit 2 with one clear line); and the options
subcommands share (the parameter table's, verbosity, progress)."""
from __future__ import annotations

import argparse
import sys

from ..base.errors import UsageError
from ..settings import parameters_of


class HelpFormatter(argparse.HelpFormatter):
    """Shows an option's default at the end of its help unless the help already says it (as
    the parameter table's help does), so that no option of any subcommand hides its default."""

    def _get_help_string(self, action) -> str:
        text = action.help or ""
        default = action.default
        if (default not in (None, False, argparse.SUPPRESS) and not action.required
                and "default" not in text.lower() and action.nargs not in (argparse.REMAINDER,)
                and not isinstance(action, (argparse._StoreTrueAction, argparse._StoreFalseAction))):
            shown = ",".join(map(str, default)) if isinstance(default, (list, tuple)) else default
            text += f" (default {shown})".replace("%", "%%")
        return text


class ArgumentParser(argparse.ArgumentParser):
    def __init__(self, *args, **kwargs):
        kwargs.setdefault("formatter_class", HelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message):
        self.print_usage(sys.stderr)
        raise UsageError(message)


def phases_for(args):
    """The progress bars of a subcommand (m3c2kit.base.phases): none with -q, always with --progress,
    otherwise when stderr is a terminal."""
    from ..base.phases import Phases

    if getattr(args, "quiet", False):
        if getattr(args, "progress", False):  # both asked: one would be silently ignored
            raise UsageError("--progress would change nothing in this run: -q/--quiet shows no progress bar")
        return Phases(enabled=False)
    return Phases(enabled=True if getattr(args, "progress", False) else None)


def add_progress_option(parser) -> None:
    parser.add_argument("--progress", action="store_true",
                        help="show the progress bars on stderr even when it is not a terminal "
                             "(default: only on a terminal)")


def add_verbosity_options(parser) -> None:
    talk = parser.add_mutually_exclusive_group()
    talk.add_argument("-q", "--quiet", action="store_true",
                      help="no progress bar or summary (warnings and errors still go to stderr)")
    talk.add_argument("--verbose", action="store_true", help="also print the parameters the run used")


def add_table_options(parser, command: str, groups: dict | None = None) -> None:
    """One option per parameter of `command` in the parameter table (m3c2kit.settings.table).
    Every default is None (not given): the table fills it in, so --params values and
    --compat defaults can tell what the user said."""
    for param in parameters_of(command):
        target = (groups or {}).get(param.name, parser)
        if param.cli_type is None:
            target.add_argument(param.flag, dest=param.name, action="store_true", default=None,
                                help=param.help_text())
        else:
            target.add_argument(param.flag, dest=param.name, type=param.cli_type, choices=param.choices,
                                metavar=param.metavar, help=param.help_text())

