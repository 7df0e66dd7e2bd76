"""The one atomic writer of the package: every file any command writes (point tables, rasters, the
report and its PNGs, analysis tables) goes through :func:`staged_outputs` (several files, all or
nothing) or :func:`atomic_output` (one file).

Each temporary lives inside a PRIVATE folder created beside its target (``mkdtemp``, mode 0700,
named ``.m3c2-tmp-<pid>-XXXXXXXX``): nobody else can enter it, so no one can swap the temporary for
a symbolic link while a writer that insists on a path writes it (issue 15), its short name
(``part`` plus the target's extension, which writers dispatching on it need) fits beside any legal
output name, and no ``*.laz`` glob in the target's folder matches it. When the body returns, each
temporary is opened without following links, given its final mode with ``fchmod`` (the replaced
file's, else the umask's default) and fsynced through that descriptor, renamed onto its target,
and the target's folder fsynced. A failure removes every private folder and leaves each target as
it was. Private folders that a killed run left behind are removed by the next run writing there
(:func:`remove_stale`): their pid is no longer alive.
"""
from __future__ import annotations

import os
import re
import shutil
import tempfile
import warnings
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from ..errors import CloudWriteError, M3C2Error
from ..fault_hook import checkpoint as fault_checkpoint

__all__ = ["atomic_output", "staged_outputs", "private_folder", "remove_stale", "PRIVATE_PREFIX"]

PRIVATE_PREFIX = ".m3c2-tmp-"
_PRIVATE = re.compile(re.escape(PRIVATE_PREFIX) + r"(\d+)-")


def _describe(err: OSError) -> str:
    return err.strerror or str(err)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # someone else's live process
    return True


def remove_stale(directory: Path) -> None:
    """Removes the private folders in `directory` whose run (pid in the name) is dead."""
    try:
        names = os.listdir(directory)
    except OSError:
        return
    for name in names:
        match = _PRIVATE.match(name)
        if match and int(match.group(1)) != os.getpid() and not _alive(int(match.group(1))):
            shutil.rmtree(Path(directory) / name, ignore_errors=True)


def private_folder(directory: Path, target: Path | None = None) -> Path:
    """A new folder only this process can enter (0700), beside `target`, in `directory`."""
    label = target if target is not None else directory
    remove_stale(directory)
    try:
        return Path(tempfile.mkdtemp(prefix=f"{PRIVATE_PREFIX}{os.getpid()}-", dir=directory))
    except FileNotFoundError:
        raise CloudWriteError(f"{label}: cannot write: directory {str(directory)!r} does not exist") from None
    except NotADirectoryError:
        raise CloudWriteError(f"{label}: cannot write: {str(directory)!r} is not a directory") from None
    except OSError as e:
        raise CloudWriteError(f"{label}: cannot write in {str(directory)!r}: {_describe(e)}") from None


def _suffix(target: Path) -> str:
    name = target.name.lower()
    return "".join(target.suffixes[-2:]) if name.endswith(".copc.laz") else target.suffix


def _final_mode(target: Path) -> int:
    # The replaced file's permissions, else those a plain open() would give (mkdtemp's are 0700).
    try:
        return os.stat(target).st_mode & 0o7777
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


def _seal(tmp: Path, target: Path) -> None:
    """Final mode and fsync through one descriptor opened without following a link."""
    fd = os.open(tmp, os.O_RDONLY | os.O_NOFOLLOW)
    try:
        os.fchmod(fd, _final_mode(target))
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_dir(directory: Path) -> None:
    # Makes the rename itself durable; not every filesystem allows fsync on a directory.
    try:
        fd = os.open(directory, os.O_RDONLY | os.O_DIRECTORY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _public(text: str, staged: dict[Path, Path], folders: list[Path]) -> str:
    """`text` with every temporary (and private folder) named by its target (and the target's
    folder): a writer handed a temporary names it in its errors and warnings, the user never saw
    it (issue 15: every message names the user's file)."""
    for target, tmp in staged.items():
        text = text.replace(str(tmp), str(target))
    for folder in folders:
        text = text.replace(str(folder), str(folder.parent))
    return text


def _renamed(error: M3C2Error, staged: dict[Path, Path], folders: list[Path]) -> M3C2Error:
    text = str(error)
    public = _public(text, staged, folders)
    if public == text:
        return error
    try:
        return type(error)(public)
    except TypeError:  # a subclass with another constructor: keep it as it is
        return error


@contextmanager
def staged_outputs(targets) -> Iterator[dict[Path, Path]]:
    """All-or-nothing output of several files: yields {target: temporary path}, each temporary in a
    private folder beside its target and ending with the target's extension; when the body
    returns, each is sealed and renamed onto its target. If the body raises, every private folder
    is removed, no target is touched, and the exception propagates (an OSError as CloudWriteError
    naming the target). Every target's folder is checked before the body runs."""
    staged: dict[Path, Path] = {}
    folders: list[Path] = []
    caught: list = []
    try:
        for target in dict.fromkeys(Path(t) for t in targets):
            if target.is_dir():
                raise CloudWriteError(f"{target}: is a directory")
            folder = private_folder(target.parent, target)
            folders.append(folder)
            staged[target] = folder / f"part{_suffix(target)}"
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                yield staged
        except M3C2Error as e:
            renamed = _renamed(e, staged, folders)
            if renamed is e:
                raise
            raise renamed from e.__cause__
        finally:
            for w in caught:  # shown as the caller's filters say, naming the targets
                warnings.warn_explicit(_public(str(w.message), staged, folders), w.category, w.filename, w.lineno)
        fault_checkpoint("writing")  # a testing aid (docs/errors.md, "Interruption"): temporaries complete
        for target, tmp in staged.items():
            if not tmp.exists():
                raise CloudWriteError(f"{target}: was not written")
            _seal(tmp, target)
        for target, tmp in staged.items():
            os.replace(tmp, target)
            _fsync_dir(target.parent)
    except OSError as e:
        if isinstance(e, CloudWriteError):
            raise
        target = next((t for t, tmp in staged.items() if e.filename in (str(tmp), tmp)), None)
        target = target or (next(iter(staged)) if len(staged) == 1 else None)
        where = target or (_public(str(e.filename), staged, folders) if e.filename else "output")
        raise CloudWriteError(f"{where}: {_describe(e)}") from e
    finally:
        for folder in folders:
            shutil.rmtree(folder, ignore_errors=True)


@contextmanager
def atomic_output(path: str | os.PathLike) -> Iterator[Path]:
    """One file through :func:`staged_outputs`: yields its temporary path."""
    target = Path(path)
    with staged_outputs([target]) as staged:
        yield staged[target]
