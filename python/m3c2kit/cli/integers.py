"""Integer options of the analysis and classify subcommands, bounded where argparse reads them.

argparse's ``type=int`` takes any integer; one past what its consumer holds (the engine's
32-bit counts and thread count, numpy's unsigned 64-bit seeds) surfaced as a binding's
TypeError or a numpy ValueError deep in the run. Each option instead names its range, and a
value outside it is a usage error naming the option (exit 2)."""
from __future__ import annotations

import argparse

__all__ = ["COUNT_MAX", "THREADS_MAX", "SEED_MAX", "integer"]

COUNT_MAX = 2**32 - 1  # the engine's std::uint32_t counts
THREADS_MAX = 2**31 - 1  # the engine's int thread count
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
    return parse
