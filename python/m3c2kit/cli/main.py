"""The `m3c2` command line: parse, read, compute, write. Exit 0 on success, 2 for usage errors,
1 for failures (unreadable input, unwritable output, interruption); no partial output file."""
from __future__ import annotations

import argparse
import os
import re
import signal
import sys
import warnings

from ..base import interrupt, portable
from ..base.errors import M3C2Error, M3C2Warning, UsageError, printable
from ..base.interrupt import Interrupted  # noqa: F401 - the stop of a run, for callers of main()


#: make_parser's default: every subcommand's parser built (the docs, the tests, the fuzzer).
EVERY_COMMAND = "*"


def make_parser(command: str | None = EVERY_COMMAND) -> argparse.ArgumentParser:
    """The `m3c2` parser. `command`: build that subcommand's parser only, the others listed by
    name and help (cli/command_index.py) without importing their modules; None: list them all,
    which is all `m3c2 --help` or an unknown command needs (issue 45: `--help` took 0.8 s)."""
    from importlib import import_module
    from .command_index import COMMANDS
    from .parser import ArgumentParser
    parser = ArgumentParser(prog="m3c2", description="M3C2 point-cloud change detection (Lague et al. 2013)")
    parser.add_argument("--version", action="version", version=_version_text())
    sub = parser.add_subparsers(dest="command", required=True, parser_class=ArgumentParser)
    built = list(COMMANDS) if command == EVERY_COMMAND else [command] if command in COMMANDS else []
    for name in built:
        module, builder, _ = COMMANDS[name]
        if name not in sub._name_parser_map:  # else added with another (analysis_parsers adds five)
            getattr(import_module(f".{module}", __package__), builder)(sub)
    for name, (_, _, text) in COMMANDS.items():
        if name not in sub._name_parser_map:
            sub.add_parser(name, help=text, add_help=False)  # listed only: never parsed (not the command)
    return parser


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
    # SIGINT, SIGHUP, SIGQUIT and SIGTERM (Windows: SIGINT, SIGTERM and SIGBREAK; base/portable.py)
    # end the run: an exception that unwinds through the atomic writer, which removes its private
    # folders (no partial output, no leftover); one that Python swallowed is raised again before
    # anything is published (base/interrupt.py). A signal the caller ignores (nohup, a shell's
    # background job) stays ignored.
    stops = [s for s in portable.stop_signals() if signal.getsignal(s) is not signal.SIG_IGN]
    with interrupt.handled(stops), warnings.catch_warnings():
        warnings.simplefilter("always", M3C2Warning)
        warnings.showwarning = _show_warning
        return _main(argv)


def _interrupted(stop: BaseException) -> int:
    """A stop (SIGINT, SIGTERM, ...): before any output was published, nothing was written (exit
    1). After one was, the run stops there: what it published is whole (io/atomic.py) and said,
    and the process ends by the signal itself, as a stopped program does (without POSIX signals,
    Windows: exit status 128 + the signal's number, as a shell reports it). A stop a step
    reworded (a series store's: what it kept) is said as it is."""
    generic = re.fullmatch(r"interrupted by (\w+); no output written", str(stop))
    name = "SIGINT" if isinstance(stop, KeyboardInterrupt) and not str(stop) else generic and generic.group(1)
    written = interrupt.published()
    if not name or not written:
        text = f"interrupted by {name}; no output written" if name else printable(stop)
        print(f"m3c2: error: {text}", file=sys.stderr)
        return 1
    print(f"m3c2: error: interrupted by {name} after writing {', '.join(map(str, written))} (whole); "
          f"nothing after it was written", file=sys.stderr)
    sys.stderr.flush()
    number = int(getattr(signal, name))
    portable.end_by_signal(number)
    if not portable.CAPS.posix_signals:
        return 128 + number
    return 1  # where the signal does not end the process (a caller that handles it itself)


def _main(argv) -> int:
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _show_warning
            # The imports a run starts with, inside the handlers: a SIGINT while laspy loads is the
            # clean "interrupted" of any other moment, not a traceback (issue 42).
            words = [str(a) for a in (sys.argv[1:] if argv is None else argv)]
            from .command_index import COMMANDS
            command = words[0] if words and words[0] in COMMANDS else None
            if command is not None:  # the top-level help and an unknown command read no file
                from ..io import laspy_local
                if argv is None and laspy_local.names_las_file(sys.argv[1:]):
                    laspy_local.import_laspy_for_local_files()
            # A value starting with "-" (`--orient -z`) is its option's: m3c2kit.cli.parser.ArgumentParser.
            args = make_parser(command).parse_args(words)
            # --threads bounds LAZ coding too, as its help says (compare adds its --params file's).
            from ..io import laz_threads
            laz_threads.set_threads(getattr(args, "threads", None) or 0)
            code = args.run(args)
            sys.stdout.flush()  # a closed stdout raises here, not in the interpreter's final flush
            return code
    except UsageError as e:
        print(f"m3c2: error: {printable(e)}", file=sys.stderr)
        return 2
    except (KeyboardInterrupt, interrupt.Interrupted) as e:
        return _interrupted(e)
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
