"""The one portability layer (m3c2kit.base.portable, issue 44): each POSIX path detected by
feature, the switch that turns them all off (M3C2_PORTABLE_FALLBACKS=1), and the behaviours the
package promises, run with the fallbacks on Linux: the store lock refuses a second writer, the
atomic writer publishes whole files and never uses a link swapped in, private folders, stops.
Windows' own lock (msvcrt's byte locks) runs against a stand-in built on lockf. The existing
tests of series/, io/, base/, cli/ and qgis_runner/ run under the switch too (scripts/test.sh);
docs/architecture.md, "Portability", lists each path, its fallback and what the user loses."""
from __future__ import annotations

import ast
import errno
import importlib.util
import os
import signal
import stat
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from m3c2kit.base import portable
from m3c2kit.base.errors import CloudWriteError
from child_env import child_env

ROOT = Path(__file__).resolve().parents[3]
PACKAGE = ROOT / "python" / "m3c2kit"
PLUGIN = ROOT / "qgis" / "m3c2kit_processing"


@pytest.fixture
def fallbacks():
    """Every POSIX path off in this process, as M3C2_PORTABLE_FALLBACKS=1 sets it at import."""
    with portable.use(portable.fallbacks()) as caps:
        yield caps


def _child(code: str, *args, env: dict | None = None) -> subprocess.CompletedProcess:
    """`code` in a child interpreter, with the fallbacks forced unless `env` says otherwise."""
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code), *map(str, args)],
                          env=child_env(**{portable.ENV: "1"}) if env is None else env,
                          capture_output=True, text=True, timeout=120)


# --------------------------------------------------------------------------- the switch itself

def test_each_capability_is_found_by_feature_and_the_switch_turns_every_one_off():
    found = portable.detect()
    assert found.record_locks == hasattr(portable.fcntl, "lockf")
    assert found.nofollow == hasattr(os, "O_NOFOLLOW")
    assert found.fd_paths == (found.folder_fds and os.path.isdir("/proc/self/fd"))
    assert found.procfs == os.path.isfile("/proc/self/status")
    assert found.byte_locks == (portable.msvcrt is not None)
    off = portable.fallbacks()
    assert not any(getattr(off, name) for name in off._fields if name != "byte_locks")
    assert off.byte_locks == found.byte_locks  # not POSIX: kept as found


@pytest.mark.parametrize("value, forced", [("1", True), ("yes", True), ("0", False), ("", False)])
def test_the_environment_variable_is_read_once_at_import(value, forced):
    done = _child("""
        from m3c2kit.base import portable
        print(portable.FORCED, portable.CAPS == portable.fallbacks(), portable.CAPS == portable.detect())
    """, env=child_env(**{portable.ENV: value}))
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == [str(forced), str(forced), str(not forced)]


def test_the_plugin_reads_the_same_switch(monkeypatch):
    """The QGIS plugin cannot import m3c2kit: its portable.py is a documented duplicate."""
    spec = importlib.util.spec_from_file_location("plugin_portable", PLUGIN / "portable.py")
    for value, continued in (("1", None), ("", getattr(signal, "SIGCONT", None))):
        monkeypatch.setenv(portable.ENV, value)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        assert module.ENV == portable.ENV and module.CONTINUE == continued


# Calls only the portability layer may make: POSIX-only (or Linux-only, or Windows-only) modules,
# attributes and keywords, and /proc paths.
_MODULES = {"fcntl", "msvcrt", "resource", "termios", "pwd", "grp", "posix", "ctypes"}
_OS = {"O_NOFOLLOW", "O_DIRECTORY", "O_CLOEXEC", "O_NONBLOCK", "O_BINARY", "O_NOINHERIT", "geteuid", "getuid",
       "fchmod", "pread", "pwrite", "killpg", "setsid", "getpgid", "sysconf", "confstr", "fork", "kill",
       "set_blocking", "supports_dir_fd", "supports_fd"}
_SIGNAL = {"SIGHUP", "SIGQUIT", "SIGKILL", "SIGPIPE", "SIGCONT", "SIGSTOP", "SIGUSR1", "SIGUSR2", "SIGALRM",
           "SIGCHLD", "SIGBREAK", "CTRL_BREAK_EVENT", "pthread_kill", "SIG_DFL"}
_KEYWORDS = {"dir_fd", "src_dir_fd", "dst_dir_fd", "start_new_session", "preexec_fn", "creationflags"}


def _posix_uses(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(), str(path))
    docstrings = {id(node.body[0].value) for node in ast.walk(tree)
                  if isinstance(node, (ast.Module, ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))
                  and node.body and isinstance(node.body[0], ast.Expr) and isinstance(node.body[0].value, ast.Constant)}
    found = []
    for node in ast.walk(tree):
        use = None
        if isinstance(node, ast.Import):
            use = ", ".join(f"import {a.name}" for a in node.names if a.name.split(".")[0] in _MODULES)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").split(".")[0] in _MODULES:
            use = f"from {node.module}"
        elif isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name):
            if (node.value.id == "os" and node.attr in _OS) or (node.value.id == "signal" and node.attr in _SIGNAL):
                use = f"{node.value.id}.{node.attr}"
        elif isinstance(node, ast.keyword) and node.arg in _KEYWORDS:
            use = f"{node.arg}="
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and "/proc/" in node.value \
                and id(node) not in docstrings:
            use = repr(node.value)
        if use:
            found.append(f"{path.relative_to(ROOT)}:{getattr(node, 'lineno', 0)} {use}")
    return found


@pytest.mark.slow
def test_every_posix_path_is_in_the_portability_layer():
    exempt = {PACKAGE / "base" / "portable.py", PLUGIN / "portable.py"}
    files = [p for p in sorted(PACKAGE.rglob("*.py")) + sorted(PLUGIN.rglob("*.py")) if p not in exempt]
    uses = [use for path in files for use in _posix_uses(path)]
    assert uses == [], "\n".join(uses)
    assert _posix_uses(PACKAGE / "base" / "portable.py")  # the scan sees them where they are


# ----------------------------------------------------------------------- opening without O_NOFOLLOW

def test_the_checked_open_refuses_a_link_and_one_swapped_in_during_the_open(fallbacks, tmp_path, monkeypatch):
    victim = tmp_path / "victim"
    victim.write_text("precious")
    link = tmp_path / "link"
    link.symlink_to(victim)
    with pytest.raises(OSError) as caught:
        portable.open_nofollow(link, os.O_RDONLY)
    assert caught.value.errno == portable.ELOOP
    plain = tmp_path / "plain"
    plain.write_text("mine")
    real_open = os.open

    def swapping_open(path, flags, mode=0o777, **kw):  # the attacker acts between the lstat and the open
        if os.fspath(path) == str(plain):
            os.replace(link, plain)
        return real_open(path, flags, mode, **kw)

    monkeypatch.setattr(os, "open", swapping_open)
    with pytest.raises(OSError) as caught:
        portable.open_nofollow(plain, os.O_RDONLY)
    assert caught.value.errno == portable.ELOOP and victim.read_text() == "precious"


def test_a_folder_held_by_name_refuses_every_call_once_swapped(fallbacks, tmp_path):
    (tmp_path / "f").mkdir()
    with portable.Folder(tmp_path / "f") as folder:
        assert not folder.held and folder.pinned() == str(tmp_path / "f")
        fd = folder.open("a", os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        os.close(fd)
        assert folder.listdir() == ["a"]
        os.rename(tmp_path / "f", tmp_path / "moved")
        (tmp_path / "f").mkdir()
        for call in (folder.listdir, lambda: folder.lstat("a"), lambda: folder.mkdir("b"), lambda: folder.unlink("a"),
                     lambda: folder.open("c", os.O_WRONLY | os.O_CREAT)):
            with pytest.raises(portable.FolderReplaced):
                call()
    assert os.listdir(tmp_path / "f") == [] and os.listdir(tmp_path / "moved") == ["a"]
    (tmp_path / "real").mkdir()
    (tmp_path / "linked").symlink_to(tmp_path / "real")
    with pytest.raises(OSError) as caught:
        portable.Folder(tmp_path / "linked", follow=False)
    assert caught.value.errno == portable.ELOOP


def test_positional_io_and_modes_without_pread_or_fchmod(fallbacks, tmp_path):
    path = tmp_path / "f"
    fd = portable.open_nofollow(path, os.O_RDWR | os.O_CREAT, 0o600)
    try:
        portable.write_at(fd, b"hello world", 0)
        portable.write_at(fd, b"W", 6)
        assert portable.read_at(fd, 100, 0) == b"hello World" and portable.read_at(fd, 5, 6) == b"World"
        portable.chmod_open(fd, 0o640, path)
        assert stat.S_IMODE(path.stat().st_mode) == 0o640
        os.rename(path, tmp_path / "g")
        path.write_text("another file under the name")
        with pytest.raises(OSError):
            portable.chmod_open(fd, 0o600, path)  # the name leads elsewhere now: never chmod-ed
        assert stat.S_IMODE(path.stat().st_mode) != 0o600 or path.stat().st_ino == os.fstat(fd).st_ino
    finally:
        os.close(fd)


# ------------------------------------------------------------------------------ the atomic writer

def test_the_atomic_writer_publishes_whole_files_and_leaves_nothing(fallbacks, tmp_path):
    from m3c2kit.io.atomic import atomic_output, staged_directory, staged_outputs
    from m3c2kit.io.private import LOCK_NAME, PRIVATE_PREFIX
    target = tmp_path / "out.csv"
    target.write_text("older")
    target.chmod(0o640)
    with atomic_output(target) as tmp:
        assert not str(tmp).startswith(portable.FD_PATH_PREFIX)  # the folder's name: no /proc here
        (name,) = [p.name for p in tmp_path.iterdir() if p.name.startswith(PRIVATE_PREFIX)]
        assert stat.S_IMODE((tmp_path / name).stat().st_mode) == 0o700
        assert (tmp_path / name / LOCK_NAME).is_file()
        tmp.write_text("new\n" * 1000)
    assert target.read_text() == "new\n" * 1000 and stat.S_IMODE(target.stat().st_mode) == 0o640
    a, b = tmp_path / "a.txt", tmp_path / "b.txt"
    with pytest.raises(RuntimeError):
        with staged_outputs([a, b]) as staged:
            staged[a].write_text("half")
            raise RuntimeError("boom")
    with staged_directory(tmp_path / "store") as folder:
        (folder / "zarr.json").write_text("{}")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.csv", "store"]
    assert sorted(p.name for p in (tmp_path / "store").iterdir()) == ["zarr.json"]


@pytest.mark.parametrize("swap", ["a folder", "a link"])
def test_a_private_folder_swapped_during_a_run_is_never_published(fallbacks, tmp_path, swap):
    """Held by name, the writes follow the swap (the fallback's weaker guarantee), but the seal
    sees it: nothing is renamed onto the target, and no file is written through a link's target
    beyond the writer's own temporary."""
    from m3c2kit.io.atomic import atomic_output
    from m3c2kit.io.private import LOCK_NAME, PRIVATE_PREFIX
    target = tmp_path / "out.csv"
    target.write_text("older")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    with pytest.raises(CloudWriteError, match="replaced by someone else"):
        with atomic_output(target) as tmp:
            (name,) = [p.name for p in tmp_path.iterdir() if p.name.startswith(PRIVATE_PREFIX)]
            os.rename(tmp_path / name, tmp_path / "moved")
            if swap == "a folder":
                (tmp_path / name).mkdir()
            else:
                (tmp_path / name).symlink_to(elsewhere, target_is_directory=True)
            tmp.write_text("new")
    assert target.read_text() == "older"
    # Ours, renamed away, is out of reach by name: only its lock file is left in it.
    assert sorted(p.name for p in (tmp_path / "moved").iterdir()) == [LOCK_NAME]
    # What took its name received the temporary (a link: its target did), never an output.
    assert (elsewhere / "part.csv").exists() == (swap == "a link")


def test_without_locks_an_abandoned_private_folder_is_left_alone(fallbacks, tmp_path):
    from m3c2kit.io.atomic import atomic_output
    from m3c2kit.io.private import LOCK_NAME, PRIVATE_PREFIX
    abandoned = tmp_path / f"{PRIVATE_PREFIX}abandoned"
    abandoned.mkdir(mode=0o700)
    (abandoned / LOCK_NAME).write_bytes(b"")
    with atomic_output(tmp_path / "x.csv") as tmp:
        tmp.write_text("x")
    assert sorted(p.name for p in tmp_path.iterdir()) == [abandoned.name, "x.csv"]  # nothing proves it abandoned


def test_staging_and_regular_bytes_without_o_nofollow(fallbacks, tmp_path):
    from m3c2kit.series import integrity
    store = tmp_path / "store"
    store.mkdir()
    staged = integrity.make_staging(store)
    assert staged == store / integrity.STAGING and integrity.staged_name(store, "a") == staged / "a"
    integrity.remove_staging(store)
    assert not staged.exists()
    (tmp_path / "file").write_bytes(b"bytes")
    assert integrity.regular_bytes(tmp_path / "file") == b"bytes"
    (tmp_path / "link").symlink_to(tmp_path / "file")
    os.mkfifo(tmp_path / "fifo")
    for bad in ("link", "fifo"):
        with pytest.raises(OSError):
            integrity.regular_bytes(tmp_path / bad)  # refused at once: never followed, never blocks


# --------------------------------------------------------------------------------- the store lock

_HOLD = """
    import sys, time
    from pathlib import Path
    from m3c2kit.series import lock
    held = lock.acquire(Path(sys.argv[1]), "test-holder")
    print("held", flush=True)
    time.sleep(60)
"""


def _holder(store: Path, prelude: str = "") -> subprocess.Popen:
    """A child holding the store's lock: with the fallbacks forced, after `prelude` when given."""
    code = textwrap.dedent(prelude) + textwrap.dedent(_HOLD)
    child = subprocess.Popen([sys.executable, "-c", code, str(store)], env=child_env(**{portable.ENV: "1"}),
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    line = child.stdout.readline().strip()
    assert line == "held", child.stderr.read()
    return child


def test_without_file_locks_the_store_lock_is_a_file_made_exclusively(fallbacks, tmp_path):
    from m3c2kit.series import lock
    from m3c2kit.series.store import StoreError
    store = tmp_path / "store"
    store.mkdir()
    assert lock.lock_name() == lock.EXCLUSIVE_NAME and not lock.moves_with_folder()
    child = _holder(store)
    try:
        with pytest.raises(StoreError, match=f"another m3c2 is writing this store \\(.*pid {child.pid}, step "
                                             f"test-holder.*run second again when it has finished"):
            lock.acquire(store, "second")
    finally:
        child.kill()
        child.wait()
    # A killed writer's file stays (nothing drops it): refused, naming the file to remove.
    with pytest.raises(StoreError, match=f"if none is .*remove {store / lock.EXCLUSIVE_NAME} first"):
        lock.acquire(store, "third")
    (store / lock.EXCLUSIVE_NAME).unlink()
    held = lock.acquire(store, "fourth")
    with pytest.raises(StoreError, match="another writing step of this process"):
        lock.acquire(store, "fifth")
    held.release()
    assert os.listdir(store) == []  # released: removed
    lock.acquire(store, "sixth").release()


_FAKE = """
    import fcntl, os, types
    def locking(fd, mode, nbytes):  # msvcrt.locking's contract, on a byte range at the position
        how = {fake.LK_NBLCK: fcntl.LOCK_EX | fcntl.LOCK_NB, fake.LK_UNLCK: fcntl.LOCK_UN}[mode]
        try:
            fcntl.lockf(fd, how, nbytes, os.lseek(fd, 0, os.SEEK_CUR))
        except OSError as e:
            raise OSError(13, "Permission denied") from e
    fake = types.SimpleNamespace(LK_NBLCK=2, LK_UNLCK=0, locking=locking)
"""
#: A child's prelude: the stand-in installed, every POSIX path off but for it.
_FAKE_MSVCRT = _FAKE + """
    from m3c2kit.base import portable
    portable.msvcrt = fake
    portable.CAPS = portable.fallbacks()._replace(byte_locks=True)
"""


@pytest.fixture
def byte_locks(monkeypatch):
    """Windows' lock tier: msvcrt.locking, played by lockf on the same byte range."""
    namespace: dict = {}
    exec(textwrap.dedent(_FAKE), namespace)
    monkeypatch.setattr(portable, "msvcrt", namespace["fake"])
    with portable.use(portable.fallbacks()._replace(byte_locks=True)) as caps:
        yield caps


def test_with_msvcrt_byte_locks_a_killed_writers_lock_is_dropped(byte_locks, tmp_path):
    from m3c2kit.series import lock
    from m3c2kit.series.store import StoreError
    store = tmp_path / "store"
    store.mkdir()
    assert lock.lock_name() == lock.LOCK_NAME
    child = _holder(store, prelude=_FAKE_MSVCRT)
    try:
        with pytest.raises(StoreError, match=f"another m3c2 is writing this store \\(.*pid {child.pid}, "
                                             f"step test-holder"):
            lock.acquire(store, "second")
    finally:
        child.kill()
        child.wait()
    held = lock.acquire(store, "third")  # the system dropped the dead holder's lock
    assert "step third" in (store / lock.LOCK_NAME).read_text()
    held.release()
    assert (store / lock.LOCK_NAME).read_text() == ""


@pytest.mark.slow
def test_with_msvcrt_byte_locks_only_an_abandoned_private_folder_is_removed(byte_locks, tmp_path):
    from m3c2kit.io.atomic import atomic_output
    from m3c2kit.io.private import LOCK_NAME, PRIVATE_PREFIX
    code = textwrap.dedent(_FAKE_MSVCRT) + textwrap.dedent("""
        import sys
        from m3c2kit.io.atomic import atomic_output
        with atomic_output(sys.argv[1]) as tmp:
            tmp.write_text("half")
            print("ready", flush=True)
            sys.stdin.read() if sys.argv[2] == "live" else os.kill(os.getpid(), 9)
    """)
    for kind in ("killed", "live"):
        child = subprocess.Popen([sys.executable, "-c", code,
                                  str(tmp_path / f"{kind}.csv"), kind], env=child_env(), stdin=subprocess.PIPE,
                                 stdout=subprocess.PIPE, text=True)
        assert child.stdout.readline() == "ready\n"
        if kind == "killed":
            child.wait()
            (killed,) = [p for p in tmp_path.iterdir() if p.name.startswith(PRIVATE_PREFIX)]
            assert (killed / LOCK_NAME).read_bytes() == b"live"
    try:
        with atomic_output(tmp_path / "x.csv") as tmp:
            tmp.write_text("x")
        left = [p for p in tmp_path.iterdir() if p.name.startswith(PRIVATE_PREFIX)]
        assert len(left) == 1 and left[0] != killed  # the dead run's folder removed, the live one's kept
    finally:
        child.stdin.close()
        assert child.wait(timeout=60) == 0
    assert (tmp_path / "live.csv").read_text() == "half" and (tmp_path / "x.csv").read_text() == "x"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["live.csv", "x.csv"]


# ---------------------------------------------------------------------------------------- signals

def test_signals_that_do_not_exist_are_skipped(fallbacks):
    assert portable.stop_signals() == (signal.SIGINT, signal.SIGTERM)
    with portable.use(portable.detect()):
        assert set(portable.stop_signals()) == {signal.SIGINT, signal.SIGHUP, signal.SIGQUIT, signal.SIGTERM}


def test_without_posix_signals_a_stop_after_a_publication_exits_128_plus_n():
    probe = """
        import signal, sys
        from m3c2kit.base import interrupt
        from m3c2kit.cli import main as m
        with interrupt.handled([signal.SIGINT]):
            interrupt.note_published(["out.csv"])
            sys.exit(m._interrupted(KeyboardInterrupt()))
    """
    done = _child(probe)
    assert done.returncode == 128 + signal.SIGINT
    assert done.stderr == ("m3c2: error: interrupted by SIGINT after writing out.csv (whole); nothing after it was "
                           "written\n")


@pytest.mark.slow
@pytest.mark.parametrize("signal_name", ["SIGINT", "SIGTERM"])
def test_a_stop_while_writing_leaves_the_older_output_and_nothing_else(tmp_path, signal_name):
    """The fault hook raises the signal in the process (signal.raise_signal: Windows' os.kill
    would end it without a handler); the run unwinds through the atomic writer by name."""
    source = tmp_path / "in.xyz"
    source.write_text("".join(f"{i} {i % 7} {i % 3}\n" for i in range(50)))
    out = tmp_path / "out.ply"
    out.write_text("older")
    env = child_env(**{portable.ENV: "1", "M3C2_TEST_SIGNAL_AT": f"writing:{signal_name}"})
    done = subprocess.run([sys.executable, "-m", "m3c2kit", "convert", str(source), "-o", str(out)], env=env,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 1 and f"interrupted by {signal_name}; no output written" in done.stderr, done.stderr
    assert out.read_text() == "older" and sorted(p.name for p in tmp_path.iterdir()) == ["in.xyz", "out.ply"]


# ----------------------------------------------------------------------------------------- memory

def test_without_proc_memory_is_unknown_and_nothing_is_trimmed(fallbacks, monkeypatch):
    from m3c2kit.io import guard
    from m3c2kit.run import memory
    assert portable.resident_bytes() == 0 == memory.rss_bytes()
    assert portable.meminfo_available() is None and portable.free_pages_bytes() is None
    assert portable.malloc_trim() is None
    memory.release_memory()  # a no-op, not an error
    monkeypatch.setattr(guard, "_CGROUP_FILES", ())
    monkeypatch.delenv(guard.MEMORY_ENV, raising=False)
    assert guard.available_memory() is None  # unknown: the in-memory check is skipped
    monkeypatch.setenv(guard.MEMORY_ENV, "1000")
    assert guard.available_memory() == 1000


# --------------------------------------------------------------------------------- the QGIS runner

def test_the_plugin_stops_a_child_by_sigterm_alone_without_posix_signals(monkeypatch):
    spec = importlib.util.spec_from_file_location("plugin_portable", PLUGIN / "portable.py")
    monkeypatch.setenv(portable.ENV, "1")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"], **module.popen_options())
    stopped = time.monotonic()
    module.stop(child)
    assert child.wait(timeout=30) == -signal.SIGTERM and time.monotonic() - stopped < 30
    assert module.STOP_NAME == "SIGTERM" and module.popen_options() == {}


def test_the_error_numbers_the_fallbacks_use_exist():
    assert portable.ELOOP == errno.ELOOP
