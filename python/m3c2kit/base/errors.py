"""Errors the m3c2 package reports to its users.

The command line maps them to exit codes: :class:`UsageError` exits 2, every other
:class:`M3C2Error` exits 1. Anything else escaping the package is a bug.

Read and write errors always start with the file path, ``f"{path}: {problem}"``, so a message
alone tells the user which file to look at.
"""
from __future__ import annotations

__all__ = ["M3C2Error", "UsageError", "CloudReadError", "CloudWriteError", "Cancelled", "M3C2Warning",
           "QuantisationWarning", "printable"]


class M3C2Error(Exception):
    """Base of every error the CLI reports as a failure (exit status 1)."""


class UsageError(M3C2Error):
    """A bad option or parameter value (exit status 2)."""


class CloudReadError(M3C2Error):
    """A point-cloud file could not be read; the message starts with ``"{path}: "``."""


class CloudWriteError(M3C2Error):
    """A point-cloud file could not be written; the message starts with ``"{path}: "``.

    Raised only after any partial output has been removed.
    """


class Cancelled(M3C2Error):
    """The progress callback stopped a run by returning False (exit status 1)."""


class M3C2Warning(UserWarning):
    """A run that is legitimate but likely mis-parameterised (m3c2kit.run.diagnostics, docs/errors.md)."""


class QuantisationWarning(M3C2Warning):
    """LAS/LAZ output rounds coordinates by more than their float64 resolution (the message
    starts with the output's path)."""


# C0 controls but tab and newline, DEL, and C1 controls (U+0080-U+009F: U+009B is a one-byte
# CSI on terminals that honour C1). Also the bidirectional overrides and isolates, which reorder
# what a terminal shows (a file name that displays as another's).
_UNPRINTABLE = {c: f"\\x{c:02x}" for c in (*range(0x00, 0x09), *range(0x0B, 0x20), 0x7F)}
_UNPRINTABLE.update({c: f"\\x{c:02x}" for c in range(0x80, 0xA0)})
_UNPRINTABLE.update({c: f"\\u{c:04x}" for c in (*range(0x202A, 0x202F), *range(0x2066, 0x206A))})


def printable(text: object) -> str:
    """`text` safe to print on a terminal: every control character but newline and tab (ESC
    starts the sequences that move the cursor, recolour, retitle the window or rewrite the
    screen) written as a visible escape (``\\x1b``), as are DEL, the C1 controls and the
    bidirectional overrides. Apply to everything printed that comes from a file or a file name
    (error messages, ``m3c2 info``)."""
    return str(text).translate(_UNPRINTABLE)
