"""Every parser of the command line, with the words that reach it: m3c2's subcommands, and the
`m3c2 series` forms, which parse their own words (m3c2kit.cli.series)."""
from __future__ import annotations

import argparse

from m3c2kit.cli import series as series_cli
from m3c2kit.cli.main import make_parser


def _walk(parser, path):
    yield " ".join(path), parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _walk(sub, path + [name])


def every_parser():
    """(words, parser) for every parser, "m3c2" first."""
    yield from _walk(make_parser(), ["m3c2"])
    yield "m3c2 series REFERENCE", series_cli.create_parser()
    for word, build in series_cli.PARSERS.items():
        yield f"m3c2 series {word}", build()
