"""Runs the installed `m3c2` command for an algorithm: found through the provider's setting or
PATH, its command line logged (shlex-quoted, to rerun it in a shell), its progress bars turned
into the feedback's percent, Cancel turned into SIGTERM (Windows: Ctrl-Break; portable.py) (m3c2
unwinds through its atomic writer: no output, no temporary left; docs/errors.md, "Interruption"),
its error message into the Processing log and a QgsProcessingException.

QGIS's Python and m3c2kit's environment stay apart: nothing here imports m3c2kit."""
import json
import os
import re
import shlex
import shutil
import signal
import subprocess
import threading
import time

from qgis.core import QgsProcessingException

from . import portable

SETTING = "M3C2_EXECUTABLE"
NOT_FOUND = ("m3c2 not found: install m3c2kit (the plugin's help, help/qgis.md in its folder, says how) or set its "
             "path in Settings > Options > Processing > Providers > m3c2kit > m3c2 executable (" + SETTING + ")")

# `m3c2 ... --progress json` writes one JSON line per update on stderr, {"phase", "done", "total",
# "percent"}: the run's percent, monotone, from m3c2's own table of its phases (m3c2kit.base.phases).
_PROGRESS = '{"phase"'
_MESSAGE = re.compile(r"m3c2: (?:(?P<kind>warning|error): )?(?P<text>.*)")
POLL_S = 0.1
#: After Cancel's SIGTERM, how long m3c2 has to unwind (it removes its private folders) before it
#: is killed: a child that ignores the TERM (or hangs) never holds QGIS (the hostile harness,
#: tests/python/qgis_runner).
KILL_AFTER_S = 5.0
#: How long the pipes' readers may outlive the child: a grandchild that inherited them (a shell
#: wrapper's background job) must not hold the algorithm open.
READERS_AFTER_EXIT_S = 2.0
#: The longest line kept whole: longer output without a line break is cut here, so that memory
#: stays bounded whatever the child prints.
LONGEST_LINE = 64 * 1024
#: The lines of stdout kept for the algorithm (its result); beyond them, only the count.
MOST_LINES = 100_000


def _setting() -> str:
    try:
        from processing.core.ProcessingConfig import ProcessingConfig
    except ImportError:  # a bare PyQGIS script without the Processing plugin: PATH only
        return ""
    return (ProcessingConfig.getSetting(SETTING) or "").strip()


def executable() -> str:
    """The m3c2 command: the provider's setting when set (it must exist), else PATH."""
    configured = _setting()
    if configured:
        if os.path.isfile(configured) and os.access(configured, os.X_OK):
            return configured
        raise QgsProcessingException(f"m3c2 not found at {configured} (the m3c2kit provider's setting {SETTING}): "
                                     "install m3c2kit (the plugin's help, help/qgis.md in its folder) or correct the setting")
    found = shutil.which("m3c2")
    if found is None:
        raise QgsProcessingException(NOT_FOUND)
    return found


def path_argument(path) -> str:
    """A file path as m3c2 reads a path, never an option (issue 42: an input named `--help` printed
    the help, an output starting with `-` failed after the run): a relative path that starts with
    '-' gets './'. Absolute paths (`/...`, `C:\\...`) never start with '-'."""
    text = str(path)
    return os.path.join(".", text) if text.startswith("-") else text


def quoted(command) -> str:
    return " ".join(shlex.quote(str(a)) for a in command)


def progress_of(line: str):
    """The run's percent in one line of `m3c2 --progress json`, or None for any other line."""
    text = line.strip()
    if not text.startswith(_PROGRESS):
        return None
    try:
        percent = float(json.loads(text)["percent"])
    except (ValueError, KeyError, TypeError):
        return None
    if percent != percent or percent in (float("inf"), float("-inf")):  # NaN or infinite: no progress
        return None
    return min(max(percent, 0.0), 100.0)


class _Stream(threading.Thread):
    """Reads one pipe of the child to its end, cutting it at \\r and \\n."""

    def __init__(self, pipe, handle):
        super().__init__(daemon=True)
        self.pipe, self.handle, self.lines = pipe, handle, []

    def run(self):
        pending = ""
        try:
            while True:
                chunk = self.pipe.read1(4096) if hasattr(self.pipe, "read1") else self.pipe.read(4096)
                if not chunk:
                    break
                pending += chunk.decode("utf-8", "replace")
                parts = re.split(r"[\r\n]", pending)
                pending = parts.pop()
                for part in parts:
                    self._line(part)
                while len(pending) > LONGEST_LINE:  # no line break for 64 KiB: cut, memory stays bounded
                    self._line(pending[:LONGEST_LINE])
                    pending = pending[LONGEST_LINE:]
        except (OSError, ValueError):  # the pipe failed under us: what was read is kept
            return
        if pending:
            self._line(pending)

    def _line(self, text):
        if len(self.lines) < MOST_LINES:
            self.lines.append(text)
        self.handle(text)


class Run:
    """One m3c2 run: stdout lines, stderr messages, the exit status."""

    def __init__(self, command, feedback, progress=False, echo=True):
        self.command = [str(a) for a in command]
        self.feedback = feedback
        self.progress = progress
        self.echo = echo  # False: stdout is data for the plugin (m3c2 info --json), not the log's
        self.errors = []
        self.last_line = ""  # of stderr: the message of a crash that printed no "m3c2: error:"

    def _stdout(self, line):
        if self.echo and line.strip() and self.feedback is not None:
            self.feedback.pushConsoleInfo(line)

    def _stderr(self, segment):
        percent = progress_of(segment)
        if percent is not None:  # the progress, never the log's
            if self.progress and self.feedback is not None:
                self.feedback.setProgress(percent)
            return
        text = segment.strip()
        if not text:
            return
        self.last_line = text
        match = _MESSAGE.search(text)
        if match is not None and match["kind"] == "error":
            self.errors.append(match["text"])
            if self.feedback is not None:
                self.feedback.reportError(match["text"], True)
        elif match is not None and match["kind"] == "warning":
            if self.feedback is not None:
                self.feedback.pushWarning(match["text"])
        elif self.feedback is not None:
            (self.feedback.pushConsoleInfo if match is None else self.feedback.pushInfo)(text)

    def execute(self) -> str:
        """Runs the command to its end; its stdout. Raises QgsProcessingException when it fails or
        is cancelled (then m3c2 has written nothing: its atomic writer)."""
        if self.feedback is not None:
            self.feedback.pushCommandInfo(quoted(self.command))
        try:
            child = subprocess.Popen(self.command, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, **portable.popen_options())
        except OSError as e:
            raise QgsProcessingException(f"cannot run {self.command[0]}: {e.strerror or e}") from None
        out, err = _Stream(child.stdout, self._stdout), _Stream(child.stderr, self._stderr)
        out.start()
        err.start()
        cancelled_at = None
        killed = False
        while child.poll() is None:
            if cancelled_at is None and self.feedback is not None and self.feedback.isCanceled():
                cancelled_at = time.monotonic()
                portable.stop(child)  # SIGTERM: m3c2 turns it into a clean exit without outputs (cli/main.py)
            elif cancelled_at is not None and not killed and time.monotonic() - cancelled_at > KILL_AFTER_S:
                killed = True
                child.kill()  # it ignored the TERM: QGIS is never held by a child that does not stop
            time.sleep(POLL_S)
        for stream, pipe in ((out, child.stdout), (err, child.stderr)):
            stream.join(READERS_AFTER_EXIT_S)
            if not stream.is_alive():  # else a grandchild holds it: the (daemon) reader is left to it
                pipe.close()
        if cancelled_at is not None:
            how = f"killed (it ignored {portable.STOP_NAME}; it may have left a temporary file)" if killed else \
                f"stopped ({portable.STOP_NAME}) and wrote no output"
            raise QgsProcessingException(f"cancelled: m3c2 was {how}")
        if child.returncode != 0:
            raise QgsProcessingException("; ".join(self.errors) or self._failure(child.returncode))
        return "\n".join(out.lines)

    def _failure(self, code: int) -> str:
        """The message of a run that ended without m3c2's own error line (a crash, a signal)."""
        if code < 0:
            try:
                name = signal.Signals(-code).name
            except ValueError:
                name = f"signal {-code}"
            status = f"killed by {name}"
        else:
            status = f"exit status {code}"
        return f"m3c2 failed ({status}){': ' + self.last_line if self.last_line else ''}"


def run(arguments, feedback, progress=False, echo=True) -> str:
    """`m3c2 ARGUMENTS...`; its stdout (logged unless `echo` is False)."""
    return Run([executable(), *arguments], feedback, progress, echo).execute()
