"""The command line's argument parser class, shared by every subcommand's parsers (m3c2kit.cli,
m3c2kit.series.cli): argparse's own usage errors become UsageError (exit 2 with one clear line)."""
from __future__ import annotations

import argparse
import sys

from .errors import UsageError


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
    """The progress bars of a subcommand (m3c2kit.phases): none with -q, always with --progress,
    otherwise when stderr is a terminal."""
    from .phases import Phases

    if getattr(args, "quiet", False):
        if getattr(args, "progress", False):  # both asked: one would be silently ignored
            raise UsageError("--progress would change nothing in this run: -q/--quiet shows no progress bar")
        return Phases(enabled=False)
    return Phases(enabled=True if getattr(args, "progress", False) else None)


def add_progress_option(parser) -> None:
    parser.add_argument("--progress", action="store_true",
                        help="show the progress bars on stderr even when it is not a terminal "
                             "(default: only on a terminal)")
