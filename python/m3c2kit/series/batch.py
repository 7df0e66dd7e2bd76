"""The one writer of a series run's epochs: whatever computed them (this process, one epoch at a
time, or Dask workers), their columns are committed here, in epoch order, by the process that
holds the store's lock (series/lock.py); workers only read."""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..base.errors import M3C2Error
from ..engine.result import Result
from . import step
from . import store as st


@dataclass(frozen=True)
class Target:
    """Where a run's epochs go: `store` as the user named it (every message names it), `folder`
    the store pinned by its writing step (every write goes there: step.writing), `index` the
    epoch the run's first one becomes."""

    store: Path
    folder: Path
    index: int


def epoch_columns(core: np.ndarray, raw: dict) -> dict:
    """The store's per-epoch columns: those of m3c2 compare's table (Result.columns)."""
    table = Result.from_engine(core, raw, {}).columns()
    return {name: table[name] for name in st.EPOCH_COLUMNS}


def with_kept(error: M3C2Error, target: Target, planned: int) -> M3C2Error:
    """`error` with what the store kept of this run (step.committed_epochs_text): the message
    of an epoch that failed after others were committed said nothing of them. An interruption is
    left to step.guarded, which says the same."""
    if step.is_interruption(error):
        return error
    kept = step.committed_epochs_text(target.store, target.folder, target.index, planned,
                                      f"resume with: m3c2 series add {target.store} EPOCH...")
    return type(error)(f"{error}; {kept}")


class Batch:
    """The epochs computed but not yet committed, committed together (store.append_batch) when
    the next one would start a new epoch chunk, when they hold more than MAX_BYTES, when the
    oldest waited MAX_SECONDS, and when the run ends, also by an error (the epochs before the
    failing one are kept, as when each was committed alone). Writing whole chunks at once instead
    of one column per epoch (each column rewrote every chunk it touched and every array's
    metadata) was 90 % of a series' time (docs/performance.md). A kill loses at most the
    batch's computation: the store stays at its last commit (store.py). Epochs are added in
    epoch order: the k-th added is epoch target.index + k."""

    MAX_BYTES = 256 << 20
    MAX_SECONDS = 60.0

    def __init__(self, target: Target, n_core: int, log):
        self.store, self.index, self.log = target.folder, target.index, log
        self.chunk = st.epoch_chunk(target.folder)
        self.epoch_bytes = n_core * 64  # 8 columns of at most 8 bytes
        self.pending: list = []
        self.started = 0.0

    def add(self, columns: dict, info: dict, path) -> None:
        if not self.pending:
            self.started = time.monotonic()
        self.pending.append((columns, info, path))
        end = self.index + len(self.pending)
        if (end % self.chunk == 0 or len(self.pending) * self.epoch_bytes >= self.MAX_BYTES
                or time.monotonic() - self.started >= self.MAX_SECONDS):
            self.commit()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> bool:
        self.commit()
        return False

    def commit(self) -> None:
        if not self.pending:
            return
        pending, self.pending = self.pending, []  # a failed commit is not tried again on the way out
        st.append_batch(self.store, self.index, [(c, i) for c, i, _ in pending])
        self.pending = pending
        for k, (_, _, path) in enumerate(self.pending):
            self.log(f"epoch {self.index + k}: {path} committed")
        self.index += len(self.pending)
        self.pending = []
