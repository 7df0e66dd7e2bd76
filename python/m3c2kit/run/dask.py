"""Tiles as tasks on a Dask distributed cluster (docs/scaling.md): the connection, bounded in time
and made before any work (a TCP probe of the scheduler's handshake, then the client), the
submission window that keeps at most two tasks per worker in flight, and the waits for tasks,
bounded too (ClusterWatch: a lost scheduler, or no worker alive, ends the run naming them)."""
from __future__ import annotations

import time
import uuid
from typing import Callable

from ..base.errors import M3C2Error
from ..base.optional import require

#: Seconds to reach a Dask scheduler and complete its handshake: an address that accepts and never
#: answers waited forever, a closed local port took 30 s (distributed's default) to say so.
DASK_CONNECT_TIMEOUT = 10.0


def connect(address: str):
    """A distributed.Client of `address`, every wait bounded by DASK_CONNECT_TIMEOUT, or an
    M3C2Error naming --dask-scheduler: refused at once when nothing listens (a TCP probe before
    distributed's retries), a timeout when the address accepts but never answers, and a clear
    message when something other than a Dask scheduler answers (its bytes read as a message
    length made "Unable to allocate 3.07 EiB")."""
    Client = require("distributed", extra="dask", purpose="running on a Dask cluster (--dask-scheduler)").Client
    where = str(address).split("://", 1)[-1]
    host, _, port = where.rpartition(":")
    if host and port.isdigit():
        _probe_scheduler(address, host.strip("[]"), int(port))
    try:
        return Client(address, timeout=DASK_CONNECT_TIMEOUT)
    except (MemoryError, OverflowError, ValueError, TypeError) as e:
        raise M3C2Error(f"--dask-scheduler {address}: the service there did not answer as a Dask scheduler "
                        f"({type(e).__name__}); check the address and port") from None
    except Exception as e:  # noqa: BLE001 - timeouts and every other connection failure are the address's
        raise M3C2Error(f"--dask-scheduler {address}: no answer from a Dask scheduler within "
                        f"{DASK_CONNECT_TIMEOUT:g} s ({type(e).__name__}: {e})") from None


#: A Dask scheduler opens every connection with its handshake: one message whose first 8 bytes
#: are its length (uint64, little-endian; ~60 bytes). Longer than this is not a scheduler.
_DASK_HANDSHAKE_MAX = 2**26


def _probe_scheduler(address: str, host: str, port: int) -> None:
    """Connects to (host, port) and reads the first 8 bytes a Dask scheduler sends, within
    DASK_CONNECT_TIMEOUT; an M3C2Error naming --dask-scheduler when that fails."""
    import socket
    import struct
    try:
        conn = socket.create_connection((host, port), timeout=DASK_CONNECT_TIMEOUT)
    except ConnectionRefusedError:
        raise M3C2Error(f"--dask-scheduler {address}: connection refused (no scheduler listens there)") from None
    except OSError as e:
        raise M3C2Error(f"--dask-scheduler {address}: cannot connect: {e.strerror or e}") from None
    with conn:
        head = b""
        try:
            while len(head) < 8:
                chunk = conn.recv(8 - len(head))
                if not chunk:
                    break
                head += chunk
        except OSError:  # socket.timeout among them
            raise M3C2Error(f"--dask-scheduler {address}: no answer within {DASK_CONNECT_TIMEOUT:g} s: the address "
                            f"accepts connections but no Dask scheduler speaks there") from None
    if len(head) < 8 or not 0 < struct.unpack("<Q", head)[0] <= _DASK_HANDSHAKE_MAX:
        raise M3C2Error(f"--dask-scheduler {address}: the service there did not answer as a Dask scheduler "
                        f"(first bytes {head!r}); check the address and port")



#: Seconds a run waits while no worker is alive before it gives up, naming the lost workers: the
#: only worker of a cluster without a nanny died and nothing would ever compute its task (the run
#: waited for ever). A worker restarted by its nanny, or a new one, joins well within it. A worker
#: the scheduler has not heard from for as long (stopped, frozen, cut off: its heartbeats, every
#: 0.5 to a few seconds, stopped) is not alive either: the scheduler itself drops it only after
#: its worker-ttl (5 minutes), and the run then waited 6 minutes, not 60 s (issue 42).
DASK_NO_WORKER_TIMEOUT = 60.0
#: Seconds between two looks at the scheduler's workers while no awaited task finishes.
DASK_POLL_INTERVAL = 1.0


class ClusterWatch:
    """Waits for tasks on a Dask cluster with every wait bounded (issue 31): between polls of the
    futures it asks the scheduler for its workers (the question bounded by DASK_CONNECT_TIMEOUT);
    a scheduler that no longer answers, or futures cancelled by a lost connection (which gave
    "TypeError: 'FutureCancelledError' object is not subscriptable"), and no worker alive for
    DASK_NO_WORKER_TIMEOUT are M3C2Errors naming the scheduler, the lost workers and the task."""

    def __init__(self, client, address: str | None = None):
        self.client = client
        self.address = address or getattr(client.scheduler, "address", "?")
        self.seen: set[str] = set()  # the address of every worker seen alive in this run
        # worker -> (its last heartbeat's time on the scheduler's clock, when this run saw it
        # change on its own monotonic clock): the two clocks are never compared.
        self.heard: dict[str, tuple[float, float]] = {}
        self.none_since: float | None = None
        self.workers = len(self._workers(lambda: "the run's tasks"))  # those alive as the run starts

    def wait(self, futures, what) -> set:
        """The futures of `futures` that are finished, once at least one is; `what()` names the
        awaited task(s) in the errors."""
        distributed = require("distributed", extra="dask", purpose="running on a Dask cluster (--dask-scheduler)")
        futures = list(futures)
        while True:
            try:
                with self.client.as_current():
                    distributed.wait(futures, timeout=DASK_POLL_INTERVAL, return_when="FIRST_COMPLETED")
            except Exception:  # noqa: BLE001 - a timeout, or cancelled futures: told apart below
                pass
            done = {f for f in futures if f.done()}
            if any(f.cancelled() for f in done) or self.client.status not in ("running", "connecting"):
                raise self.scheduler_lost(what())
            if done:
                return done
            self._check_workers(what)

    def scheduler_lost(self, what: str) -> M3C2Error:
        return M3C2Error(f"--dask-scheduler {self.address}: the connection to the scheduler was lost (it stopped or "
                         f"became unreachable); {what} not computed")

    def _workers(self, what) -> dict:
        """The scheduler's live workers (remembered in self.seen), asked within DASK_CONNECT_TIMEOUT:
        those it heard from within DASK_NO_WORKER_TIMEOUT."""
        try:
            identity = self.client.sync(self.client.scheduler.identity, n_workers=-1,
                                        callback_timeout=DASK_CONNECT_TIMEOUT)
            workers = dict(identity.get("workers", {}))
        except Exception:  # noqa: BLE001 - no answer within the bound, or a closed connection
            raise self.scheduler_lost(what()) from None
        now = time.monotonic()
        for name, info in workers.items():
            beat = info.get("last_seen") if isinstance(info, dict) else None
            if beat is None or name not in self.heard or self.heard[name][0] != beat:  # None: no heartbeat told
                self.heard[name] = (beat, now)
        alive = {name: info for name, info in workers.items() if now - self.heard[name][1] < DASK_NO_WORKER_TIMEOUT}
        self.seen.update(workers)
        return alive

    def _check_workers(self, what) -> None:
        if self._workers(what):
            self.none_since = None
            return
        now = time.monotonic()
        if self.none_since is None:
            self.none_since = now
        if now - self.none_since >= DASK_NO_WORKER_TIMEOUT:
            lost = ", ".join(sorted(self.seen)) or "none had joined"
            raise M3C2Error(f"--dask-scheduler {self.address}: no worker alive for {DASK_NO_WORKER_TIMEOUT:g} s "
                            f"(lost workers: {lost}); {what()} not computed")


def execute(tasks, task_fn, accept, *, client=None, retries: int = 3, log=lambda s: None, args=(),
            ordered: bool = False, describe: Callable[[object, int], str] | None = None,
            address: str | None = None) -> int:
    """Computes task_fn(task, *args) for every task exactly once and hands each result to
    accept(); returns the number of workers (1 on this machine). THE executor of tasks (a tiled
    run's tiles and classification tiles; a series' epochs can use it the same way):

    - `client` None: on this machine, one task at a time, the memory handed back between tasks
      (m3c2kit.run.memory.release_memory), in task order;
    - a distributed.Client: at most two tasks per worker pending (the submission window), each
      retried `retries` times by Dask, every wait bounded (ClusterWatch: a lost scheduler, or no
      worker alive, ends the run naming them); results handed over as they finish, or with
      `ordered` in task order, a new task submitted only once the oldest is handed over (so at
      most the window's results wait in memory).

    `log` is told the progress every 5 %. A task's own error propagates. `describe(task, k)`
    names the k-th task in the errors of a wait ("epoch 3 (b.laz)"; default: "tile 3 of 17");
    `address`: the scheduler as the user gave it, for those errors."""
    if client is None:
        from .memory import release_memory
        for i, task in enumerate(tasks):
            accept(task_fn(task, *args))
            release_memory()
            _progress(log, i + 1, len(tasks), _kind(task_fn))
        return 1
    return _on_dask(client, list(tasks), task_fn, accept, retries=retries, log=log, args=args, ordered=ordered,
                    describe=describe, address=address)


def _kind(task_fn) -> str:
    return "tile" if "tile" in getattr(task_fn, "__name__", "tile") else "task"


def _progress(log, done: int, total: int, kind: str) -> None:
    if done % max(1, total // 20) == 0:
        log(f"{kind} {done}/{total}")


def _label(task, k: int):
    """A task's number in keys and messages: its tile's, else its place in the run."""
    return getattr(task, "tile", k)


def _on_dask(client, tasks: list, task_fn, accept, *, retries: int, log, args, ordered: bool, describe,
             address) -> int:
    watch = ClusterWatch(client, address)
    workers = max(1, watch.workers)
    run_id = uuid.uuid4().hex[:8]
    window = max(2, 2 * workers)
    name = getattr(task_fn, "__name__", "tile")
    kind = _kind(task_fn)
    running: dict = {}  # future -> (its place in the run, its task)
    submitted = []      # the futures in task order (ordered runs)

    def submit_next() -> None:
        k = len(submitted)
        if k == len(tasks):
            return
        task = tasks[k]
        future = client.submit(task_fn, task, *args, key=f"m3c2-{name}-{run_id}-{_label(task, k)}",
                               retries=retries, pure=False)
        running[future] = (k, task)
        submitted.append(future)

    def awaited(futures) -> str:
        if describe is not None:
            return ", ".join(describe(running[f][1], running[f][0]) for f in sorted(futures, key=lambda f: running[f][0]))
        numbers = sorted(_label(running[f][1], running[f][0]) for f in futures)
        shown = ", ".join(map(str, numbers[:5])) + (", ..." if len(numbers) > 5 else "")
        return f"{kind}{'s' if len(numbers) > 1 else ''} {shown} of {len(tasks)}"

    def hand_over(future, done: int) -> None:
        out = future.result()  # a task's own error propagates, as before
        del running[future]
        accept(out)
        future.release()
        _progress(log, done, len(tasks), kind)
        submit_next()

    for _ in range(window):
        submit_next()
    done = 0
    while running:
        if ordered:  # the oldest task, whatever order they finish in
            oldest = submitted[done]
            watch.wait([oldest], lambda: awaited([oldest]))
            finished = [oldest]
        else:
            pending = list(running)
            finished = watch.wait(pending, lambda: awaited(pending))
        for future in finished:
            done += 1
            hand_over(future, done)
    return workers
