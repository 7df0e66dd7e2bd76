"""The command line's argument parser class, shared by every subcommand's parsers (m3c2kit.cli,
m3c2kit.series.cli): argparse's own usage errors become UsageError (exit 2 with one clear line)."""
from __future__ import annotations

import argparse
import sys

from .errors import UsageError


class ArgumentParser(argparse.ArgumentParser):
    def error(self, message):
        self.print_usage(sys.stderr)
        raise UsageError(message)
