"""One view of a series store for the steps that analyse it (issue 41): smooth and objects
(series/analysis.py), kalman (series/kalman.py) and tam3c2 (series/tam3c2.py) each opened the
store, read its core points and times, split its core chunks into blocks, staged variables shaped
like `distance` and published them, each with its own copy of that scaffolding or reaching into
analysis.py's private helpers. :class:`StoreView` and :func:`writing` are that scaffolding, once.

Kill-safety: a step writes its new variables whole in the store's staging folder (integrity.STAGING,
invisible to zarr and xarray; :meth:`StoreView.staged`), then publishes them (:func:`publish_many`):
a kill or a full disk while it computes or writes leaves the previous variables whole and in use;
a kill inside the publication leaves them marked half-written (store.REWRITING), which every later
step refuses, naming the step to rerun."""
from __future__ import annotations

import json
import os
import shutil
from contextlib import contextmanager
from pathlib import Path
from typing import Callable

import numpy as np

from ..base.errors import M3C2Error, UsageError
from .. import engine as facade
from . import integrity
from . import parameters
from . import step
from . import store as st

MICROSECONDS_PER_DAY = 86_400_000_000


def core_chunks(group, name: str = "distance") -> list[tuple[int, int]]:
    """[begin, end) of each of the store's chunks of array `name` along the core points."""
    n, chunk = group[name].shape[0], group[name].chunks[0]
    return [(b, min(n, b + chunk)) for b in range(0, n, chunk)]


def variable_spec(group, dtype, fill, attrs: dict, extra: tuple[str, int] | None = None) -> dict:
    """A (core, epoch) array's settings, shaped and chunked like `distance`. `extra`: (name, size)
    of a third dimension, whole in every chunk (the Kalman filter's moments)."""
    model = group["distance"]
    dims, shape, chunks = ("core", "epoch"), model.shape, model.chunks
    attributes = dict(attrs, coordinates="time")
    if extra is not None:
        name, size = extra
        # No `coordinates` there: the moments have never carried it, and a store's bytes stay the same.
        dims, shape, chunks, attributes = (*dims, name), (*shape, size), (*chunks, size), dict(attrs)
    return dict(shape=shape, chunks=chunks, dtype=dtype, fill_value=fill, compressors=st.codecs(),
                dimension_names=dims, attributes=attributes)


def new_variable(store: Path, name: str, dtype, fill, attrs: dict):
    """(group, array): a (core, epoch) array in the group itself (replacing any earlier one), for a
    store nobody sees yet (an import's private folder); a published store's step stages instead
    (StoreView.staged, publish_many)."""
    _, zarr = st.require_extra()
    group = zarr.open_group(str(store), mode="r+", use_consolidated=False)
    if name in group:
        del group[name]
    array = group.create_array(name, **variable_spec(group, dtype, fill, attrs)).with_config(st.WRITE_CONFIG)
    return group, array


def publish(folder: Path, name: str) -> None:
    """Replaces the store's `name` by its staged array: marked (store.REWRITING) in one commit,
    the folders swapped, the metadata consolidated, the mark cleared in a last commit. A kill
    between the first and last commit leaves `name` marked half-written, never silently mixed."""
    publish_many(folder, [name])


def publish_many(folder: Path, names, removed=()) -> None:
    """publish() of several staged arrays as one (a step's variables that only make sense
    together, such as the Kalman filter's): all marked in one commit, swapped, the `removed`
    ones (a variable of the step's earlier run it no longer writes) deleted, consolidated, the
    marks cleared in a last commit. A kill in between leaves every one of them marked."""
    names, removed = list(names), [r for r in removed if (Path(folder) / r).exists()]
    marked = st.rewriting(st.open_group(folder))
    st.set_rewriting(folder, [*marked, *names, *removed])
    for name in names:
        target, staged = Path(folder) / name, integrity.staged_name(folder, name)  # pinned: never through a link
        old = staged.with_name(name + ".old")
        shutil.rmtree(old, ignore_errors=True)
        if target.exists():
            os.rename(target, old)
        os.rename(staged, target)
    for name in removed:
        shutil.rmtree(Path(folder) / name)
    st.commit(folder)
    st.set_rewriting(folder, [m for m in marked if m not in names and m not in removed])
    integrity.remove_staging(folder)  # the step's only: it holds the lock


def what_was_kept(store: Path, folder: Path, names: tuple[str, ...], what: str) -> str:
    """What an interrupted or failed step kept of its variables `names` (`what`, in words), from
    the store as it is now: its last commit, the half-written ones and the command that rewrites
    them, or the variables unchanged."""
    try:
        group = st.open_group(folder)
    except M3C2Error:
        return f"{store} is at its last commit"
    marked = [n for n in st.rewriting(group) if n in names]
    if marked:
        return (f"{', '.join(marked)} {'is' if len(marked) == 1 else 'are'} marked half-written in {store}; "
                f"rerun {integrity.rerun_command(group, marked[0], store)}")
    return f"{what} unchanged in {store}" if any(n in group for n in names) else f"{store} unchanged (it has no {what})"


class StoreView:
    """One store as a step reads and writes it: `shown`, the store as the user named it (every
    message names it), `folder`, the path it goes through (a writing step's pinned folder), and
    `group`, its root group as committed when the view was made. For one step's thread."""

    def __init__(self, shown: Path, folder: Path | None = None):
        self.shown = Path(shown)
        self.folder = self.shown if folder is None else Path(folder)
        self.group = st.open_group(self.folder)
        self._staging: Path | None = None  # made by the first staged(): every variable of the step in it

    @property
    def n_core(self) -> int:
        return self.group["distance"].shape[0]

    @property
    def n_epochs(self) -> int:
        return self.group["distance"].shape[1]

    @property
    def imported(self) -> bool:
        """Imported from a py4dgeo archive, which keeps no M3C2 parameters."""
        return "imported_from" in self.group.attrs

    def read(self, name: str, selection=slice(None)) -> np.ndarray:
        """store.read: a chunk that does not decode is an error naming the store and the chunk."""
        return st.read(self.shown, self.group, name, selection)

    def core(self) -> np.ndarray:
        """The core points, (N, 3) float64, C order (as the engine takes them)."""
        return np.ascontiguousarray(np.column_stack([self.read(a) for a in "xyz"]), dtype=np.float64)

    def normals(self) -> np.ndarray:
        """The core points' normals as the store oriented them (its --orient), (N, 3)."""
        return np.column_stack([self.read(a) for a in ("nx", "ny", "nz")])

    def times(self, needed_by: str) -> np.ndarray:
        """The epochs' times (int64 microseconds). `needed_by` (e.g. "the Kalman filter") needs
        every one: an epoch without a time (NaT) is refused, naming it and how to give one."""
        times = self.read("time", slice(0, self.n_epochs)).astype(np.int64)
        if (times == st.NAT).any():
            first = int(np.flatnonzero(times == st.NAT)[0])
            raise UsageError(f"{self.shown}: epoch {first} has no time (NaT): {needed_by} needs every epoch's time "
                             f"(give it in the epoch list file, 'PATH, TIME')")
        return times

    def days(self, needed_by: str, since: int | None = None) -> np.ndarray:
        """times(needed_by) in days since `since` (microseconds), the first epoch's time when None."""
        times = self.times(needed_by)
        origin = times[0] if since is None else since
        return (times - origin).astype(np.float64) / MICROSECONDS_PER_DAY

    def core_chunks(self, name: str = "distance") -> list[tuple[int, int]]:
        return core_chunks(self.group, name)

    def blocks(self, row_bytes: int, block_bytes: int) -> list[tuple[int, int]]:
        """Blocks of core points [begin, end) that bound a step's memory: the store's core chunks
        (a block never straddles one, so each chunk is read and written once), split so that one
        holds at most `block_bytes` at `row_bytes` per core point (and at least one core point)."""
        most = max(1, block_bytes // row_bytes)
        return [(b, min(end, b + most)) for begin, end in self.core_chunks() for b in range(begin, end, most)]

    def engine_params(self):
        """The store's engine Params (its cylinder, normal scales, LOD's rule and confidence). An
        imported py4dgeo store keeps no parameters: py4dgeo's LOD is 1.96 (...), z at 95 %."""
        if self.imported:
            return facade.make_params({"lod": "z", "confidence": 0.95})
        return parameters.engine_params(json.loads(self.group.attrs["parameters"]), self.core())

    def staged(self, name: str, dtype, fill, attrs: dict, extra: tuple[str, int] | None = None):
        """A new array `name` in the step's staging folder, shaped and chunked like `distance`
        (variable_spec; `extra` a third dimension), not part of the store until publish()."""
        _, zarr = st.require_extra()
        if self._staging is None:
            self._staging = integrity.make_staging(self.folder)
        return zarr.create_array(store=str(self._staging / name), zarr_format=3, config=st.WRITE_CONFIG,
                                 **variable_spec(self.group, dtype, fill, attrs, extra))

    def publish(self, names, removed=()) -> None:
        """The staged arrays `names` become the store's, the store's `removed` deleted, all as one
        (publish_many)."""
        publish_many(self.folder, names, removed)
        self._staging = None  # publish_many removed it


@contextmanager
def writing(store: Path, step_name: str, variables, what: str, *, other_outputs: Callable[[], str] | None = None):
    """step.writing for a step that replaces `variables` (`what`, in words): yields the StoreView
    of the store's pinned folder, its lock held. A failure's message says what the store kept
    (what_was_kept), after `other_outputs()`: what the step wrote besides (objects' tables)."""
    store, names = Path(store), tuple(variables)

    def kept(folder: Path) -> str:
        return (other_outputs() if other_outputs else "") + what_was_kept(store, folder, names, what)

    with step.writing(store, step_name, kept) as folder:
        yield StoreView(store, folder)
