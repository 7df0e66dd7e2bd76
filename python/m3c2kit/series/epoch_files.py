"""An epoch's file as the store knows it: the SHA-256 of its content (its identity, format 2), the
state that shows a write to it, and the provenance recorded with its columns."""
from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

from ..base.errors import M3C2Error
from . import epochs as epochs_mod


def file_digest(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def file_state(path: Path) -> tuple:
    """What a write to the file changes: device, inode, size, modification and change time. The
    change time cannot be set back (touch restores a modification time), so an edit between the
    hash of an epoch and its read, even one keeping size and mtime, is seen (require_unchanged)."""
    s = os.stat(path)
    return s.st_dev, s.st_ino, s.st_size, s.st_mtime_ns, s.st_ctime_ns


@dataclass(frozen=True)
class HashedEpoch(epochs_mod.Epoch):
    """An epoch to add with the SHA-256 of its file's content (its identity in the store)."""
    sha256: str = ""
    state: tuple = ()  # file_state when the hash was taken


def require_unchanged(epoch) -> None:
    """After an epoch is read: its file is the one hashed (HashedEpoch.state), or an M3C2Error;
    else the store would keep one content's SHA-256 with another content's distances."""
    if getattr(epoch, "state", ()) and file_state(epoch.path) != epoch.state:
        raise M3C2Error(f"{epoch.path}: changed while this run read it (its size, inode or times differ from when "
                        f"its SHA-256 was taken); it is not added: rerun when the file is written whole")


def identity(path: Path) -> tuple[str, int, int]:
    """Resolved path, size and modification time (a format 1 store's identity of an epoch)."""
    s = os.stat(path)
    return str(Path(path).resolve()), int(s.st_size), int(s.st_mtime_ns)


def provenance(epoch, points: int) -> dict:
    """The store's per-epoch record (store.EPOCH_INFO) of an epoch read with `points` points."""
    path, size, mtime = identity(epoch.path)
    return {"time": epoch.time, "source": path, "source_size": size, "source_mtime_ns": mtime,
            "time_source": epoch.time_source, "points": points,
            "source_sha256": getattr(epoch, "sha256", "") or file_digest(epoch.path)}
