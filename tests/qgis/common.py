"""What the QGIS tests share: the environment (headless, the plugin folder, the m3c2 command on
PATH after the system's Python), the Toronto pair, a tiny test runner (Debian's python3 has no
pytest)."""
import os
import shutil
import subprocess
import sys
import tempfile
import traceback

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
PLUGINS = os.path.join(ROOT, "qgis")
TORONTO = os.path.join(ROOT, "data", "toronto-ttp")
REFERENCE, COMPARED = os.path.join(TORONTO, "TTP_15.laz"), os.path.join(TORONTO, "TTP_23.laz")
# A small core set: 499 core points, a run of a second (README's demo uses spacing 5).
SMALL = ["--core-spacing", "20", "--normal-scale", "16", "--projection-scale", "10", "--max-depth", "30"]
QGIS_PROCESS = "/usr/bin/qgis_process.bin"  # /usr/bin/qgis_process passes --noversioncheck, which 3.22 rejects


def m3c2_bin() -> str:
    """The folder of the m3c2 under test: M3C2_BIN, else the repository's .venv."""
    folder = os.environ.get("M3C2_BIN", os.path.join(ROOT, ".venv", "bin"))
    if not os.path.isfile(os.path.join(folder, "m3c2")):
        sys.exit(f"no m3c2 in {folder}: install m3c2kit (scripts/install.sh) or set M3C2_BIN")
    return folder


def _runtime_dir() -> str:
    """Qt wants a private runtime folder (0700)."""
    path = os.path.join(tempfile.gettempdir(), f"m3c2kit-qgis-runtime-{os.getuid()}")
    os.makedirs(path, mode=0o700, exist_ok=True)
    os.chmod(path, 0o700)
    return path


def environment(**extra) -> dict:
    """QGIS headless. The system's bin folders come before m3c2's: QGIS's embedded Python finds its
    home through the first `python3` on PATH, which must be Debian's, not a virtual environment's."""
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen", QGIS_PLUGINPATH=PLUGINS,
               PATH=os.pathsep.join(["/usr/bin", "/bin", m3c2_bin()]), XDG_RUNTIME_DIR=_runtime_dir())
    env.pop("PYTHONHOME", None)
    env.pop("VIRTUAL_ENV", None)
    env.update(extra)
    return env


def m3c2(*args, **kwargs):
    return subprocess.run([os.path.join(m3c2_bin(), "m3c2"), *map(str, args)], capture_output=True, text=True,
                          env=environment(), **kwargs)


def qgis_process(*args, env=None, timeout=300, cwd=None):
    return subprocess.run([QGIS_PROCESS, *map(str, args)], capture_output=True, text=True,
                          env=env or environment(), timeout=timeout, cwd=cwd)


def read(path) -> bytes:
    with open(path, "rb") as f:
        return f.read()


class Folder:
    """A temporary folder, removed at the end."""

    def __enter__(self):
        self.path = tempfile.mkdtemp(prefix="m3c2kit-qgis-")
        return self.path

    def __exit__(self, *exc):
        shutil.rmtree(self.path, ignore_errors=True)


def run_tests(namespace) -> int:
    """Runs every test_* function of `namespace` (a module's globals); the exit status."""
    tests = [(name, f) for name, f in namespace.items() if name.startswith("test_") and callable(f)]
    selected = sys.argv[1:]
    failed = 0
    for name, test in tests:
        if selected and not any(s in name for s in selected):
            continue
        try:
            test()
        except Exception:  # noqa: BLE001 - a test runner reports every failure
            failed += 1
            print(f"FAIL {name}\n{traceback.format_exc()}", flush=True)
        else:
            print(f"ok   {name}", flush=True)
    print(f"{len(tests) - failed} passed, {failed} failed" if not selected else f"{failed} failed")
    return 1 if failed else 0
