"""docs/errors.md, "Run limits": every wait on a --dask-scheduler address is bounded (issue 15,
points 5 and 9). Only 127.0.0.1 sockets opened here: a closed port, one that accepts and never
answers, one that answers as another service."""
from __future__ import annotations

import re
import signal
import socket
import threading
import time

import numpy as np
import pytest

from m3c2kit.run import dask as dask_run
from m3c2kit.cli.main import main

pytest.importorskip("distributed")


@pytest.fixture
def pair(tmp_path, monkeypatch):
    monkeypatch.setattr(dask_run, "DASK_CONNECT_TIMEOUT", 2.0)
    rng = np.random.default_rng(0)
    for name in ("ref", "cmp"):
        xy = rng.uniform(0, 10, (500, 2))
        np.savetxt(tmp_path / f"{name}.xyz", np.column_stack([xy, rng.normal(0, 0.01, 500)]))
    return tmp_path


def run(pair, capsys, port):
    started = time.monotonic()
    code = main(["compare", str(pair / "ref.xyz"), str(pair / "cmp.xyz"), "-o", str(pair / "out.csv"),
                 "--normal-scale", "1", "--projection-scale", "1", "--max-depth", "1", "--tile-size", "5",
                 "--dask-scheduler", f"tcp://127.0.0.1:{port}", "--quiet"])
    return code, capsys.readouterr().err, time.monotonic() - started


def test_a_closed_port_fails_at_once(pair, capsys):
    """It took 30 s (distributed's connect retries) to say 'timed out'."""
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    code, err, took = run(pair, capsys, port)
    assert code == 1
    assert err == f"m3c2: error: --dask-scheduler tcp://127.0.0.1:{port}: connection refused (no scheduler listens there)\n"
    assert not (pair / "out.csv").exists()


@pytest.mark.slow
def test_an_endpoint_that_never_answers_times_out(pair, capsys):
    """It waited forever."""
    with socket.socket() as srv:
        srv.bind(("127.0.0.1", 0))
        srv.listen(8)  # the kernel accepts; nobody ever speaks
        port = srv.getsockname()[1]
        code, err, took = run(pair, capsys, port)
    assert code == 1
    assert err == (f"m3c2: error: --dask-scheduler tcp://127.0.0.1:{port}: no answer within 2 s: the address "
                   f"accepts connections but no Dask scheduler speaks there\n")


def test_a_service_that_is_not_dask_gets_a_message_about_the_address(pair, capsys):
    """Its bytes read as a message length gave 'Unable to allocate 3.07 EiB'."""
    with socket.socket() as srv:
        srv.bind(("127.0.0.1", 0))
        srv.listen(8)
        port = srv.getsockname()[1]

        def answer():
            with srv.accept()[0] as conn:
                conn.sendall(b"HTTP/1.1 400 Bad Request\r\n\r\n")
                time.sleep(0.5)

        threading.Thread(target=answer, daemon=True).start()
        code, err, took = run(pair, capsys, port)
    assert code == 1
    assert err == (f"m3c2: error: --dask-scheduler tcp://127.0.0.1:{port}: the service there did not answer as a "
                   f"Dask scheduler (first bytes b'HTTP/1.1'); check the address and port\n")
    assert "EiB" not in err


# --- issue 31: nothing hangs. Real schedulers and workers (subprocesses on 127.0.0.1, killed here):
# a series to an address that never answers, the only worker dying (no nanny), a dead scheduler.

import os  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
from contextlib import contextmanager  # noqa: E402
from pathlib import Path  # noqa: E402

from m3c2kit.base import fault_hook  # noqa: E402

SERIES_PARAMS = ["--normal-scale", "1", "--projection-scale", "1", "--max-depth", "1", "--quiet"]


def _stopped(pid: int) -> bool:
    """True once the process is stopped (state T in /proc/PID/stat)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] in ("T", "t")
    except OSError:
        return False


@contextmanager
def cluster(tmp_path, worker_signal_at: str):
    """A scheduler and one worker without a nanny, as subprocesses; the worker runs with the
    testing aid set (fault_hook: it signals itself at a phase). Yields (address, scheduler, worker)."""
    distributed = pytest.importorskip("distributed")
    info = tmp_path / "scheduler.json"
    procs = []
    try:
        scheduler = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                                      "--port", "0", "--no-dashboard", "--scheduler-file", str(info)],
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        procs.append(scheduler)
        deadline = time.monotonic() + 60
        while not info.exists() or not info.read_text().strip().endswith("}"):
            assert time.monotonic() < deadline and scheduler.poll() is None, "the scheduler did not start"
            time.sleep(0.1)
        import json
        address = json.loads(info.read_text())["address"]
        env = dict(os.environ, **{fault_hook.ENV: worker_signal_at})
        worker = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", address, "--no-nanny",
                                   "--nthreads", "1", "--host", "127.0.0.1", "--no-dashboard"], env=env,
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        procs.append(worker)
        with distributed.Client(address, timeout=30) as client:
            client.wait_for_workers(1, timeout=60)
        yield address, scheduler, worker
    finally:
        for p in procs:
            p.kill()
            p.wait(timeout=30)


@pytest.fixture
def bounded(monkeypatch):
    monkeypatch.setattr(dask_run, "DASK_NO_WORKER_TIMEOUT", 2.0)
    monkeypatch.setattr(dask_run, "DASK_POLL_INTERVAL", 0.2)


def series_files(folder: Path, epochs: int = 3) -> list[Path]:
    rng = np.random.default_rng(1)
    xy = rng.uniform(0, 6, (400, 2))
    paths = []
    for k in range(epochs + 1):
        path = folder / f"ep{k}.xyz"
        np.savetxt(path, np.column_stack([xy, 0.01 * k + rng.normal(0, 0.005, len(xy))]))
        paths.append(path)
    return paths


@pytest.mark.slow
@pytest.mark.timeout(60)
def test_series_to_an_address_that_never_answers_fails_before_creating_the_store(pair, capsys):
    """It hung over 90 s and left an empty store."""
    paths = series_files(pair, 1)
    with socket.socket() as srv:
        srv.bind(("127.0.0.1", 0))
        srv.listen(8)
        port = srv.getsockname()[1]
        started = time.monotonic()
        code = main(["series", *map(str, paths), "-o", str(pair / "st.zarr"), *SERIES_PARAMS,
                     "--dask-scheduler", f"tcp://127.0.0.1:{port}"])
        took = time.monotonic() - started
    assert code == 1 and took < 20
    assert capsys.readouterr().err == (f"m3c2: error: --dask-scheduler tcp://127.0.0.1:{port}: no answer within 2 s: "
                                       f"the address accepts connections but no Dask scheduler speaks there\n")
    assert not (pair / "st.zarr").exists()


@pytest.mark.slow
@pytest.mark.timeout(120)
def test_compare_fails_when_its_only_worker_dies(pair, capsys, tmp_path, bounded):
    """The worker kills itself in its first tile (no nanny restarts it): the run waited for ever."""
    with cluster(tmp_path, "computing:SIGKILL") as (address, _, worker):
        code, err, took = run(pair, capsys, address.rsplit(":", 1)[1])
        assert worker.wait(timeout=10) == -signal.SIGKILL
    assert code == 1, err
    assert err.startswith(f"m3c2: error: --dask-scheduler tcp://127.0.0.1:{address.rsplit(':', 1)[1]}: no worker "
                          f"alive for 2 s (lost workers: tcp://127.0.0.1:"), err
    assert re.search(r"\); tiles? [0-9, .]+ of [0-9]+ not computed\n$", err) and err.count("\n") == 1, err
    assert not (pair / "out.csv").exists()


@pytest.mark.slow
@pytest.mark.timeout(120)
def test_compare_fails_when_its_only_worker_freezes(pair, capsys, tmp_path, bounded):
    """Issue 42: the worker stops itself in its first tile (SIGSTOP: alive to the scheduler until
    its 5-minute worker-ttl); the run waited those minutes and 60 s more. A worker silent for
    DASK_NO_WORKER_TIMEOUT is not alive."""
    with cluster(tmp_path, "computing:SIGSTOP") as (address, _, worker):
        code, err, took = run(pair, capsys, address.rsplit(":", 1)[1])
        assert _stopped(worker.pid)
    assert code == 1, err
    assert err.startswith(f"m3c2: error: --dask-scheduler tcp://127.0.0.1:{address.rsplit(':', 1)[1]}: no worker "
                          f"alive for 2 s (lost workers: tcp://127.0.0.1:"), err
    assert took < 30 and err.count("\n") == 1, (took, err)
    assert not (pair / "out.csv").exists()


@pytest.mark.slow
@pytest.mark.timeout(120)
def test_series_fails_when_its_only_worker_dies_and_says_what_it_kept(pair, capsys, tmp_path, bounded):
    """The worker dies reading the reference: the store keeps its core points and no epoch, and says so."""
    paths = series_files(pair)
    store = pair / "st.zarr"
    with cluster(tmp_path, "reading:SIGKILL") as (address, _, _):
        code = main(["series", *map(str, paths), "-o", str(store), *SERIES_PARAMS, "--dask-scheduler", address])
    err = capsys.readouterr().err
    assert code == 1
    assert err == (f"m3c2: error: --dask-scheduler {address}: no worker alive for 2 s (lost workers: "
                   f"{err.split('lost workers: ')[1].split(')')[0]}); epoch 0 ({paths[1]}) not computed; no epoch of "
                   f"this run committed; {store} holds 0 epoch(s) (resume with: m3c2 series add {store} EPOCH...)\n"), err
    import xarray as xr
    assert xr.open_zarr(store).sizes["epoch"] == 0


@pytest.mark.slow
@pytest.mark.timeout(120)
@pytest.mark.parametrize("command", ["compare", "series"])
def test_a_dead_scheduler_is_named(pair, capsys, tmp_path, bounded, command):
    """The worker stops itself while computing; the scheduler is then killed. It gave
    "TypeError: 'FutureCancelledError' object is not subscriptable"."""
    paths = series_files(pair)
    phase = "computing:SIGSTOP" if command == "compare" else "reading:SIGSTOP"
    with cluster(tmp_path, phase) as (address, scheduler, worker):
        def kill_scheduler():
            deadline = time.monotonic() + 60
            while not _stopped(worker.pid) and time.monotonic() < deadline:
                time.sleep(0.05)
            scheduler.kill()

        threading.Thread(target=kill_scheduler, daemon=True).start()
        if command == "compare":
            code, err, _ = run(pair, capsys, address.rsplit(":", 1)[1])
        else:
            code = main(["series", *map(str, paths), "-o", str(pair / "st.zarr"), *SERIES_PARAMS,
                         "--dask-scheduler", address])
            err = capsys.readouterr().err
    assert code == 1, err
    assert err.startswith(f"m3c2: error: --dask-scheduler {address}: the connection to the scheduler was lost (it "
                          f"stopped or became unreachable); "), err
    assert "not computed" in err and "Traceback" not in err and err.count("\n") == 1, err
    if command == "series":
        assert err.endswith(f"no epoch of this run committed; {pair / 'st.zarr'} holds 0 epoch(s) (resume with: "
                            f"m3c2 series add {pair / 'st.zarr'} EPOCH...)\n"), err
