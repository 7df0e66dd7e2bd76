"""The command line's argument parser class, shared by every subcommand's parsers (m3c2kit.cli):
argparse's own usage errors become UsageError (exit 2 with one clear line), an option's value may
start with "-" (`--orient -10,5,3`), and the progress bars of a run (`phases_for`). The options
subcommands share are declared in m3c2kit.cli.options."""
from __future__ import annotations

import argparse
import sys

from ..base.errors import UsageError


class HelpFormatter(argparse.HelpFormatter):
    """Shows an option's default at the end of its help unless the help already says it (as
    the parameter table's help does), so that no option of any subcommand hides its default
    (0 included: `is`, as 0 == False)."""

    def _get_help_string(self, action) -> str:
        text = action.help or ""
        default = action.default
        if (not any(default is unset for unset in (None, False, argparse.SUPPRESS)) and not action.required
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

    def parse_known_args(self, args=None, namespace=None):
        # Subparsers parse their words with this method too: each joins its own options' values.
        words = sys.argv[1:] if args is None else [str(a) for a in args]
        return super().parse_known_args(self.dash_values_joined(words), namespace)

    def dash_values_joined(self, words: list[str]) -> list[str]:
        """Each value that starts with "-" joined to its option, as `--orient=-10,5,3`, unless it
        is one of this parser's options. argparse alone takes any such word but a plain negative
        number (-1, -0.5) for an unknown option and answers "expected one argument": a scanner at
        negative x (`--orient -10,5,3`), `--orient -z`, `--precision-scales -1,1` were refused,
        and `--normal-scale -1` never reached its range check."""
        out: list[str] = []
        i = 0
        while i < len(words):
            word = words[i]
            if word == "--":  # the rest is positional
                return out + words[i:]
            out.append(word)
            i += 1
            if i < len(words) and self._takes_one_value(word) and self._is_dash_value(words[i]):
                out[-1] = f"{word}={words[i]}"
                i += 1
        return out

    def _option(self, word: str):
        """The action `word` names, abbreviated or not (argparse's allow_abbrev); else None."""
        action = self._option_string_actions.get(word)
        if action is None and self.allow_abbrev and word.startswith(2 * word[:1]) and len(word) > 2:
            named = {a for s, a in self._option_string_actions.items() if s.startswith(word)}
            action = named.pop() if len(named) == 1 else None
        return action

    def _takes_one_value(self, word: str) -> bool:
        action = self._option(word) if word and word[0] in self.prefix_chars else None
        return action is not None and action.nargs in (None, 1)

    def _is_dash_value(self, word: str) -> bool:
        """Starts with "-" (more than a lone "-", which argparse reads as a value) and is not an
        option of this parser, `--name=value` or a short option with its value attached (-ofile)
        included."""
        if len(word) < 2 or word[0] not in self.prefix_chars or word == 2 * word[0]:
            return False
        name = word.split("=", 1)[0]
        return self._option(name) is None and word[:2] not in self._option_string_actions


def phases_for(args):
    """The progress bars of a subcommand (m3c2kit.base.phases): none with -q, always with --progress,
    otherwise when stderr is a terminal."""
    from ..base.phases import Phases

    if getattr(args, "quiet", False):
        if getattr(args, "progress", False):  # both asked: one would be silently ignored
            raise UsageError("--progress would change nothing in this run: -q/--quiet shows no progress bar")
        return Phases(enabled=False)
    shown = getattr(args, "progress", None)
    return Phases(enabled=True if shown else None, json=shown == "json")
