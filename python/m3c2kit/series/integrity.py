"""Is a series store whole? `m3c2 series check STORE` (:func:`check`), the fast check every step
runs on the arrays it reads (:func:`require_present`, :func:`require_whole`), and the recovery a
writer runs under the lock before it writes (:func:`recover`).

What can be proven. A format 2 store writes every chunk and checksums each (store.py), so
`check` proves that the root metadata is committed and is an m3c2kit series, that each array's
own metadata agrees with the committed shapes and the arrays agree on the core and epoch counts,
that every chunk of the committed shape is present and decodes with its checksum, and that no
variable is half-written (store.REWRITING). For a format 1 store, chunks have no checksum and an
absent chunk is legal (it reads as the fill value), so `check` proves the metadata and that the
present chunks decode, not that a chunk is missing or that its bytes are those written."""
from __future__ import annotations

import json
import os
import shutil
import stat
from pathlib import Path

from ..base import portable
from ..base.portable import Folder
from . import store as st
from .store import StoreError

#: The step that writes each derived variable: the command a half-written one is fixed by
#: ({window}: the window of the committed smoothed_distance, when there is one).
REWRITTEN_BY = {"smoothed_distance": "m3c2 series smooth {store}{window}",
                "object": "m3c2 series objects {store} -o OBJECTS.csv",
                **{name: "m3c2 series kalman {store} --from-scratch" for name in st.KALMAN_VARIABLES},
                **{name: "m3c2 series tam3c2 {store}" for name in st.TAM3C2_VARIABLES}}


def rerun_command(group, name: str, store: Path) -> str:
    """The command that rewrites the half-written variable `name` of the store."""
    window = ""
    try:
        if name in group and "window" in group[name].attrs:
            window = f" --window {int(group[name].attrs['window'])}"
    except (KeyError, TypeError, ValueError):
        pass
    return REWRITTEN_BY.get(name, "the step that writes it").format(store=store, window=window)
#: A step's private folder inside the store for arrays being written (view.publish_many): no zarr.json, so
#: neither zarr nor xarray sees it.
STAGING = ".m3c2-staging"

_STAGED: dict[str, Folder] = {}  # a store folder -> the staging folder its step made, held


def remove_staging(folder: Path) -> None:
    """Removes the staging folder of a step (or an interrupted one's). A link planted at its name
    is removed, never followed: rmtree refuses a link, so a step wrote its arrays through it and
    moved the store's previous variable into the link's target."""
    held = _STAGED.pop(os.fspath(folder), None)
    if held is not None:
        held.close()
    path = Path(folder) / STAGING
    try:
        kind = os.lstat(path).st_mode
    except FileNotFoundError:
        return
    if stat.S_ISDIR(kind):
        shutil.rmtree(path, ignore_errors=True)
    else:
        os.unlink(path)


def make_staging(folder: Path) -> Path:
    """The step's staging folder, made anew (0700) and pinned: the path returned resolves through a
    descriptor (base.portable.Folder.pinned: /proc/self/fd), so a folder or link swapped in under
    its name afterwards receives nothing (elsewhere its name: a link there is refused as it is
    opened). staged_name() is the name of an array in it for a rename."""
    remove_staging(folder)
    path = Path(folder) / STAGING
    os.mkdir(path, 0o700)  # exclusive: one planted in between is an error, never used
    held = Folder(path, follow=False)
    _STAGED[os.fspath(folder)] = held
    return Path(held.pinned())


def staged_name(folder: Path, name: str) -> Path:
    """The staged array `name` of make_staging(folder), by the pinned path while it is held."""
    held = _STAGED.get(os.fspath(folder))
    return Path(held.pinned() if held is not None else Path(folder) / STAGING) / name


def own_shape(folder: Path, name: str) -> tuple | None:
    """The shape array `name`'s own zarr.json says (past the commit after an interrupted run),
    None when the file is missing or unreadable (damage)."""
    try:
        return tuple(json.loads(regular_bytes(Path(folder) / name / "zarr.json"))["shape"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def regular_bytes(path: Path) -> bytes:
    """The bytes of `path` when it is a regular file (no link followed), else an OSError: a FIFO
    or a device planted in the store hung the reader that opened it (issue 42)."""
    with os.fdopen(portable.regular_nofollow(path), "rb") as f:
        return f.read()


def _checksummed(group) -> bool:
    return int(group.attrs.get("format_version", 1)) >= st.CHECKSUMMED_FROM


def _chunk_entries(folder: Path, name: str) -> tuple[set[str], list[str]]:
    """(the chunk files of array `name`, its entries that are no regular file nor folder): a FIFO,
    a device, a socket or a link among the chunks would hang or redirect the reader that opens it,
    so it is damage, named before any chunk is read (no link is followed)."""
    present: set[str] = set()
    special: list[str] = []

    def walk(path: str, rel: str) -> None:
        with os.scandir(path) as entries:
            for entry in entries:
                key = f"{rel}/{entry.name}"
                if entry.is_dir(follow_symlinks=False):
                    walk(entry.path, key)
                elif entry.is_file(follow_symlinks=False):
                    if not entry.name.endswith(".partial"):
                        present.add(key)
                else:
                    special.append(key)

    top = Path(folder) / name / "c"
    try:
        kind = os.lstat(top).st_mode
    except FileNotFoundError:
        return present, special
    if stat.S_ISDIR(kind):
        walk(os.fspath(top), "c")
    elif stat.S_ISREG(kind):
        present.add("c")
    else:
        special.append("c")
    return present, sorted(special)


def _chunk_files(folder: Path, name: str) -> set[str]:
    return _chunk_entries(folder, name)[0]


def special_entries(folder: Path, name: str) -> list[str]:
    """The entries of array `name`'s chunks that are no regular file (_chunk_entries)."""
    return _chunk_entries(folder, name)[1]


def missing_chunks(folder: Path, group, name: str) -> list[str]:
    """The chunk files of `name`'s committed shape that are absent (format 2: every chunk is written)."""
    array = group[name]
    present = _chunk_files(folder, name)
    return [key for key, _ in st.chunk_grid(array.shape, array.chunks) if key not in present]


def require_present(folder: Path, shown: Path | None = None) -> None:
    """The fast check every step runs before it reads or writes: every committed array has its
    zarr.json and (format 2) every chunk file of its committed shape; else a StoreError naming the
    first damage (a partial copy never reads as NaN). Decoding is checked as chunks are read
    (store.read); `m3c2 series check` does both for everything."""
    shown = folder if shown is None else shown
    group = st.open_group(folder)
    checksummed = _checksummed(group)
    for name in sorted(group.array_keys()):
        if own_shape(folder, name) is None:
            raise StoreError(f"{shown}: damaged: array {name} has no readable zarr.json (a partial copy?); "
                             f"m3c2 series check {shown} lists every damage")
        special = special_entries(folder, name)
        if special:
            raise StoreError(f"{shown}: damaged: array {name} chunk {special[0]} is not a regular file (a FIFO, "
                             f"device or link is never read); m3c2 series check {shown} lists every damage")
        missing = missing_chunks(folder, group, name) if checksummed else []
        if missing:
            raise StoreError(f"{shown}: damaged: array {name} lacks chunk {missing[0]} ({len(missing)} chunk(s) "
                             f"missing: a partial copy?); m3c2 series check {shown} lists every damage")


def require_whole(group, names, shown: Path) -> None:
    """A StoreError naming the step to rerun when one of `names` is marked half-written."""
    for name in names:
        if name in st.rewriting(group):
            raise StoreError(f"{shown}: {name} is half-written (the step writing it was interrupted); "
                             f"rerun {rerun_command(group, name, shown)}")


def recover(folder: Path) -> list[str]:
    """Brings the store at `folder` back to its last commit before a writer writes (under the
    lock): arrays resized past their committed shape by an interrupted run are cut back (their
    chunks beyond it removed), arrays never committed and the staging folder are removed.
    Without it, the next commit (a consolidation) would publish an interrupted run's half.
    Returns what it removed, for the log."""
    _, zarr = st.require_extra()
    committed = zarr.open_consolidated(str(folder), mode="r").metadata.consolidated_metadata.metadata
    done = []
    for entry in os.scandir(folder):
        if entry.is_dir(follow_symlinks=False) and entry.name not in committed \
                and (Path(entry.path) / "zarr.json").exists():
            shutil.rmtree(entry.path)
            done.append(f"uncommitted array {entry.name} removed")
    own = zarr.open_group(str(folder), mode="r+", use_consolidated=False)
    for name, meta in committed.items():
        shape = own_shape(folder, name)
        if shape is None or getattr(meta, "node_type", "array") != "array":
            continue  # a marked or damaged variable: require_present and check name it
        if shape != tuple(meta.shape):
            own[name].resize(tuple(meta.shape))
            done.append(f"array {name} cut back to its committed shape {tuple(meta.shape)}")
    remove_staging(folder)
    return done


def check(path: Path) -> tuple[list[str], list[str]]:
    """(what was found, the damages) of the store at `path`; no damage: the store is sound."""
    found: list[str] = []
    damages: list[str] = []
    path = Path(path)
    try:
        group = st.open_group(path, whole=False)
    except StoreError as e:
        return found, [str(e).removeprefix(f"{path}: ")]  # the command's lines name the store already
    damages.extend(st.committed_problems(group))
    if damages:
        return found, damages  # the root metadata is no whole store: its arrays cannot be checked against it
    version = int(group.attrs.get("format_version", 1))
    _, zarr = st.require_extra()
    committed = zarr.open_consolidated(str(path), mode="r").metadata.consolidated_metadata.metadata
    arrays = sorted(name for name, meta in committed.items() if getattr(meta, "node_type", "array") == "array")
    n_core = group["x"].shape[0] if "x" in group else None
    n_epoch = group["time"].shape[0] if "time" in group else None
    found.append(f"format {st.FORMAT} version {version}: {n_core} core point(s), {n_epoch} epoch(s), "
                 f"{len(arrays)} array(s)")
    if version < st.CHECKSUMMED_FROM:
        found.append(f"format version {version} stores no checksum and may omit chunks of fill values: "
                     f"check proves its metadata and that its present chunks decode, not that none is missing "
                     f"or altered")
    for name in st.rewriting(group):
        damages.append(f"{name}: half-written by an interrupted step; rerun {rerun_command(group, name, path)}")
    chunks = 0
    for name in arrays:
        array = group[name]
        shape = own_shape(path, name)
        if shape is None:
            damages.append(f"array {name}: its zarr.json is missing or unreadable")
            continue
        if len(shape) != len(array.shape) or any(o < c for o, c in zip(shape, array.shape)):
            damages.append(f"array {name}: its zarr.json says shape {shape}, the commit {tuple(array.shape)}")
        elif shape != tuple(array.shape):
            found.append(f"array {name}: columns past the commit {tuple(array.shape)} from an interrupted run "
                         f"(not part of the store; the next writing step removes them)")
        present, special = _chunk_entries(path, name)
        damages.extend(f"array {name} chunk {key}: not a regular file (never read)" for key in special)
        for key, selection in st.chunk_grid(array.shape, array.chunks):
            chunks += 1
            if key in special:
                continue
            if version >= st.CHECKSUMMED_FROM and key not in present:
                damages.append(f"array {name} chunk {key}: missing")
                continue
            try:
                array[selection]
            except Exception as e:  # noqa: BLE001 - any decode failure is damage
                damages.append(f"array {name} chunk {key}: cannot be decoded ({st.decode_problem(e)})")
    found.append(f"{chunks} chunk(s) {'present and ' if version >= st.CHECKSUMMED_FROM else ''}read")
    if (path / STAGING).exists():
        found.append(f"{STAGING}: arrays of an interrupted step (not part of the store; the next writing step "
                     f"removes them)")
    return found, damages
