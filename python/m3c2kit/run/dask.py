"""Tiles as tasks on a Dask distributed cluster (docs/scaling.md): the connection, bounded in time
and made before any work (a TCP probe of the scheduler's handshake, then the client), and the
submission window that keeps at most two tasks per worker in flight."""
from __future__ import annotations

import uuid

from ..errors import M3C2Error
from ..optional import require

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



def run_on_dask(client, tasks, task_fn, accept, *, retries: int, log, args=()) -> int:
    """Submits task_fn(task, *args) for every task to `client` (at most two per worker pending),
    hands each result to accept() as it completes; returns the number of workers."""
    distributed = require("distributed", extra="dask", purpose="running on a Dask cluster (--dask-scheduler)")
    workers = max(1, len(client.scheduler_info().get("workers", {})))
    run_id = uuid.uuid4().hex[:8]
    window = max(2, 2 * workers)
    pending = iter(tasks)
    name = getattr(task_fn, "__name__", "tile")
    futures = distributed.as_completed(with_results=True)

    def submit_next() -> bool:
        task = next(pending, None)
        if task is None:
            return False
        futures.add(client.submit(task_fn, task, *args, key=f"m3c2-{name}-{run_id}-{task.tile}",
                                  retries=retries, pure=False))
        return True

    for _ in range(window):
        if not submit_next():
            break
    done = 0
    for future, out in futures:
        accept(out)
        future.release()
        done += 1
        if done % max(1, len(tasks) // 20) == 0:
            log(f"tile {done}/{len(tasks)}")
        submit_next()
    return workers
