"""Numeric options of the analysis, classify and series subcommands, bounded where argparse reads them.

argparse's ``type=int`` takes any integer; one past what its consumer holds (the engine's
32-bit counts, numpy's unsigned 64-bit seeds) surfaced as a binding's TypeError or a numpy
ValueError deep in the run. Each option instead names its range, and a value outside it is a
usage error naming the option (exit 2). `--threads` is the parameter table's in every command,
with the table's range (m3c2kit.cli.options)."""
from __future__ import annotations

import argparse

from .. import engine
from ..settings.parsers import non_negative, positive

__all__ = ["COUNT_MAX", "SEED_MAX", "integer", "positive_real", "non_negative_real"]

COUNT_MAX = engine.COUNT_MAX
SEED_MAX = 2**64 - 1  # numpy's seeds are unsigned


def integer(low: int, high: int):
    """An argparse ``type`` reading an integer in [low, high]."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be an integer, got {text!r}") from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"must be an integer from {low} to {high}, got {text}")
        return value
    parse.__name__ = "integer"  # argparse names the type in its messages
    parse.bounds = (low, high)  # for a dialog built from the parser (settings.export)
    return parse


def positive_real(flag: str):
    """An argparse ``type`` reading a finite real number > 0: settings.parsers.positive's check and
    message, naming `flag` (its UsageError ends the parse with exit 2)."""
    def parse(text: str) -> float:
        return positive(flag, text)
    parse.__name__ = "positive"
    parse.bounds = (0.0, None)  # > 0 (settings.export)
    return parse


def non_negative_real(flag: str):
    """An argparse ``type`` reading a finite real number >= 0 (settings.parsers.non_negative)."""
    def parse(text: str) -> float:
        return non_negative(flag, text)
    parse.__name__ = "non_negative"
    parse.bounds = (0.0, None)  # >= 0 (settings.export)
    return parse
