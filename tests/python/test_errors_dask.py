"""docs/errors.md, "Run limits": every wait on a --dask-scheduler address is bounded (issue 15,
points 5 and 9). Only 127.0.0.1 sockets opened here: a closed port, one that accepts and never
answers, one that answers as another service."""
from __future__ import annotations

import socket
import threading
import time

import numpy as np
import pytest

from m3c2kit.run import dask as dask_run
from m3c2kit.cli import main

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
