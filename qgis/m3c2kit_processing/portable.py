"""The plugin's own POSIX-only paths, each beside the fallback another system gets (issue 44).

m3c2kit's are in m3c2kit/base/portable.py, which the plugin cannot import (QGIS's Python and
m3c2kit's environment stay apart: runner.py). This is its documented duplicate for the two things
the runner does with signals: it reads the same switch, M3C2_PORTABLE_FALLBACKS=1 (once, at import),
which turns the POSIX paths off so that the fallbacks run on Linux
(tests/python/qgis_runner/test_runner_hostile.py runs under it too; a test checks that both
modules name the same variable). Each capability is found by feature, never by the system's name.
"""
import os
import signal
import subprocess

ENV = "M3C2_PORTABLE_FALLBACKS"
FORCED = os.environ.get(ENV, "").strip() not in ("", "0")

#: POSIX: SIGCONT after Cancel's SIGTERM, since a stopped child (Ctrl-Z, SIGSTOP) would never see
#: the TERM. Fallback (none): a stopped child is killed after KILL_AFTER_S.
CONTINUE = None if FORCED else getattr(signal, "SIGCONT", None)
#: Windows: Popen.terminate is TerminateProcess, which ends m3c2 at once, its private folders left
#: for the next run to remove. Instead m3c2 runs in a process group of its own and Cancel sends it
#: Ctrl-Break, which Python raises as SIGBREAK, a clean stop for m3c2 (m3c2kit.base.portable).
#: A console event needs a console: where QGIS has none (the desktop application), sending it
#: fails and TerminateProcess ends the run as before. Not POSIX: kept as found when the fallbacks
#: are forced (Linux has none).
BREAK = getattr(signal, "CTRL_BREAK_EVENT", None)
#: What Cancel sends, for the messages.
STOP_NAME = "Ctrl-Break" if BREAK is not None else "SIGTERM"


def popen_options() -> dict:
    """Popen's keywords for an m3c2 child: on Windows, a process group of its own (Ctrl-Break
    then reaches it alone, never QGIS)."""
    if BREAK is not None:
        return {"creationflags": subprocess.CREATE_NEW_PROCESS_GROUP}
    return {}


def stop(child) -> None:
    """Asks the m3c2 `child` to stop cleanly: SIGTERM, and SIGCONT for a stopped child (POSIX);
    Ctrl-Break to its process group (Windows), else TerminateProcess."""
    if BREAK is not None:
        try:
            child.send_signal(BREAK)
            return
        except OSError:  # no console to send it through
            pass
    child.terminate()
    if CONTINUE is not None:
        try:
            os.kill(child.pid, CONTINUE)
        except OSError:
            pass
