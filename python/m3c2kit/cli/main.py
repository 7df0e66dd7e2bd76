"""The `m3c2` command line: parse, read, compute, write. Exit 0 on success, 2 for usage errors,
1 for failures (unreadable input, unwritable output, interruption); no partial output file."""
from __future__ import annotations

import argparse
import os
import signal
import sys
import warnings

from ..base import interrupt
from ..base.errors import M3C2Error, M3C2Warning, UsageError, printable
from ..base.interrupt import Interrupted  # noqa: F401 - the stop of a run, for callers of main()


def make_parser() -> argparse.ArgumentParser:
    # The subcommands' modules are imported here, not at the top: `m3c2 --version` needs none.
    from .analysis import analysis_parsers
    from .classify import classify_parsers
    from .commands import convert_parser, info_parser, normals_parser, subsample_parser
    from .compare import compare_parser
    from .parser import ArgumentParser
    parser = ArgumentParser(prog="m3c2", description="M3C2 point-cloud change detection (Lague et al. 2013)")
    parser.add_argument("--version", action="version", version=_version_text())
    sub = parser.add_subparsers(dest="command", required=True, parser_class=ArgumentParser)
    from .series import series_parsers  # noqa: PLC0415 - m3c2 series (docs/series.md)
    from .variogram import variogram_parser  # noqa: PLC0415 - m3c2 variogram (docs/analysis.md)
    from .aggregate import aggregate_parser  # noqa: PLC0415 - m3c2 aggregate (docs/analysis.md)
    for build in (compare_parser, normals_parser, subsample_parser, info_parser, convert_parser, analysis_parsers, classify_parsers,
                  series_parsers, variogram_parser, aggregate_parser):
        build(sub)
    return parser


_CLEAN_EXIT_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGHUP", "SIGQUIT", "SIGTERM")
                            if hasattr(signal, name))


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """Every warning as one line, `m3c2: warning: ...`: M3C2Warning (e.g. QuantisationWarning) by
    its text, another library's (numpy's RuntimeWarning) with its class, never with Python's
    source file and line (issue 42: numpy warnings reached the user with our source lines)."""
    text = printable(message) if issubclass(category, M3C2Warning) else f"{category.__name__}: {printable(message)}"
    print(f"m3c2: warning: {text}", file=sys.stderr)


def _version_text() -> str:
    from .. import __version__
    return f"m3c2 (m3c2kit) {__version__}"


def main(argv=None) -> int:
    """The `m3c2` command. Without `argv` (the `m3c2` script, ``python -m m3c2kit``) the process
    is the command line's own: laspy is imported without the modules a local file never uses
    (m3c2kit.io.laspy_local) when the arguments name a LAS/LAZ file."""
    words = sys.argv[1:] if argv is None else [str(a) for a in argv]
    if words == ["--version"]:  # answered before any parser or library is imported
        print(_version_text())
        return 0
    # SIGINT, SIGHUP, SIGQUIT and SIGTERM end the run: an exception that unwinds through the atomic
    # writer, which removes its private folders (no partial output, no leftover); one that Python
    # swallowed is raised again before anything is published (base/interrupt.py). A signal the
    # caller ignores (nohup, a shell's background job) stays ignored.
    stops = [s for s in _CLEAN_EXIT_SIGNALS if signal.getsignal(s) is not signal.SIG_IGN]
    with interrupt.handled(stops), warnings.catch_warnings():
        warnings.simplefilter("always", M3C2Warning)
        warnings.showwarning = _show_warning
        return _main(argv)


def _main(argv) -> int:
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _show_warning
            # The imports a run starts with, inside the handlers: a SIGINT while laspy loads is the
            # clean "interrupted" of any other moment, not a traceback (issue 42).
            from ..io import laspy_local
            if argv is None and laspy_local.names_las_file(sys.argv[1:]):
                laspy_local.import_laspy_for_local_files()
            # A value starting with "-" (`--orient -z`) is its option's: m3c2kit.cli.parser.ArgumentParser.
            args = make_parser().parse_args([str(a) for a in (sys.argv[1:] if argv is None else argv)])
            # --threads bounds LAZ coding too, as its help says (compare adds its --params file's).
            from ..io import laz_threads
            laz_threads.set_threads(getattr(args, "threads", None) or 0)
            code = args.run(args)
            sys.stdout.flush()  # a closed stdout raises here, not in the interpreter's final flush
            return code
    except UsageError as e:
        print(f"m3c2: error: {printable(e)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("m3c2: error: interrupted by SIGINT; no output written", file=sys.stderr)
        return 1
    except M3C2Error as e:
        print(f"m3c2: error: {printable(e)}", file=sys.stderr)
        return 1
    except MemoryError:
        print("m3c2: error: out of memory; use fewer or subsampled core points", file=sys.stderr)
        return 1
    except BrokenPipeError:
        # stdout closed by the reader (`m3c2 info x.las | head -1`): stop quietly, as Unix tools
        # do, and point stdout at /dev/null so that the interpreter's final flush stays quiet.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    except OSError as e:
        # An OS error no reader or writer turned into a message: e.g. a name over 255 bytes, which
        # pathlib's checks (exists, is_file) raise instead of answering. Writers remove their
        # temporaries on any exception (io.atomic), so nothing half-written is left.
        from ..io.input_file import os_error_message
        print(f"m3c2: error: {printable(os_error_message(e))}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
