"""The rule that no output is an input, for the files the series steps write beside a store
(`series report -o`, `series objects -o` and its members table; docs/errors.md, issue 31): a
store stands for more files than its folder. `report -o STORE/zarr.json` destroyed the store,
`report -o ref.las` overwrote its reference (its path is in the store's attributes)."""
from __future__ import annotations

import json
import os
from pathlib import Path

from ..base.errors import UsageError
from . import store as st


def members_path(table: Path) -> Path:
    """The members table `m3c2 series objects -o TABLE` writes beside TABLE."""
    if Path(table).name in ("", ".", ".."):
        raise UsageError(f"{os.fspath(table)!r}: names no file (an objects table is a file, OBJECTS.csv)")
    return Path(table).with_name(Path(table).stem + "_members.csv")


#: The `object` labels' attributes holding the SHA-256 of the objects and members tables written
#: with them: a report reads a table with the store's objects only (hostile round 2: a table of
#: another store was drawn over this one's core points).
TABLE_DIGESTS = ("objects_table_sha256", "members_table_sha256")


def table_digests(table: Path) -> dict:
    """TABLE_DIGESTS of the objects table `table` and its members table (regular files only)."""
    from ..io.input_file import file_sha256
    return dict(zip(TABLE_DIGESTS, (file_sha256(Path(table)), file_sha256(members_path(table)))))


def require_objects_of(store: Path, labels_attrs, table: Path) -> None:
    """A UsageError unless `table` (and its members table) is the one `m3c2 series objects`
    wrote with the store's `object` labels (`labels_attrs`: their attributes, None when the store
    has none). Labels written before the digests were recorded are taken on trust."""
    rerun = f"run m3c2 series objects {store} -o {table}"
    if labels_attrs is None:
        raise UsageError(f"--objects {table}: {store} has no object labels, so the table is not of its objects; {rerun}")
    recorded = {k: labels_attrs.get(k) for k in TABLE_DIGESTS}
    if None in recorded.values():
        return
    if table_digests(table) != recorded:
        raise UsageError(f"--objects {table}: not the objects table written with {store}'s object labels (another "
                         f"store's, another run's, or edited since); {rerun}")


def store_inputs(store: Path) -> dict:
    """The files a store stands for, labelled: its reference and its epochs' sources, as recorded."""
    attrs = st.attributes(store)  # a clear StoreError for what is not a committed store
    found = {"store's reference": attrs.get("reference") or None}
    for k, source in enumerate(st.epoch_info(store)["source"]):
        found[f"store's epoch {k} source"] = str(source) or None
    return found


def refuse_inside(outputs: dict, store: Path) -> None:
    """A UsageError for an output (label -> path) that is the store, lies inside it (through any
    link), or is a hard link to one of its files: replacing it would damage the store."""
    root = os.path.realpath(store)
    linked = None  # (device, inode) of the store's files, listed only for an output with hard links
    for label, path in outputs.items():
        if path is None:
            continue
        real = os.path.realpath(path)
        inside = real == root or real.startswith(root.rstrip(os.sep) + os.sep)
        if not inside:
            try:
                info = os.stat(path)
            except OSError:
                info = None
            if info is not None and info.st_nlink > 1:
                if linked is None:
                    linked = {(s.st_dev, s.st_ino) for s in _stats_below(root)}
                inside = (info.st_dev, info.st_ino) in linked
        if inside:
            raise UsageError(f"{label} {os.fspath(path)!r} is inside the series store {os.fspath(store)!r} (or a link "
                             f"to one of its files): writing it would damage the store; choose another output path")


def enclosing_store(path: Path) -> Path | None:
    """The series store that holds `path` (through any link), or None. Read from its root
    zarr.json's attributes alone: a damaged store protects its folder too."""
    real = Path(os.path.realpath(path))
    for folder in (real, *real.parents):
        root = folder / "zarr.json"
        if not root.is_file():  # is_file: a FIFO planted as zarr.json is never opened
            continue
        try:
            attributes = json.loads(root.read_bytes()).get("attributes") or {}
        except (OSError, ValueError, AttributeError):
            continue  # no JSON object: another tool's file, not a series store
        if isinstance(attributes, dict) and attributes.get("format") == st.FORMAT:
            return folder
    return None


def refuse_inside_any_store(outputs: dict) -> None:
    """refuse_inside for the store that holds an output, whatever store the command reads:
    `series REF EPOCH -o STORE/new` and `import -o STORE/new` wrote a store inside another."""
    for label, path in outputs.items():
        store = enclosing_store(path) if path is not None else None
        if store is not None:
            refuse_inside({label: path}, store)


def _stats_below(root: str):
    for folder, _, names in os.walk(root):
        for name in names:
            try:
                yield os.stat(os.path.join(folder, name), follow_symlinks=False)
            except OSError:
                continue
