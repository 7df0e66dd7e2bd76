"""The smoke test of an installed m3c2kit wheel: cibuildwheel runs it on every wheel it builds, on
Linux, macOS and Windows (pyproject.toml, [tool.cibuildwheel] test-command; docs/building.md,
"Wheels for each platform"), from outside the source tree. It checks what differs between the
systems (the compiled engine, the portability layer m3c2kit/base/portable.py):

1. the engine: two planes 0.5 apart give 0.5 at every core point (the API);
2. the atomic writer: `m3c2 compare` replaces an existing LAZ output whole, read back with laspy,
   and leaves no private folder behind;
3. with the series extra: `m3c2 series` creates a store, a second writer is refused while this
   process holds the store's lock (lockf on POSIX, msvcrt's byte lock on Windows), and the
   step runs once the lock is let go.

Usage: python wheel_smoke.py   (exit status 0: every check passed; it prints what it checked)."""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

PARAMS = ["--core-spacing", "2", "--normal-scale", "2", "--projection-scale", "2", "--max-depth", "2", "--quiet"]


def m3c2(*args, expect: int = 0) -> subprocess.CompletedProcess:
    """`m3c2 ARGS...` in a child interpreter; a SystemExit naming it when its status is not `expect`."""
    done = subprocess.run([sys.executable, "-m", "m3c2kit", *map(str, args)], capture_output=True, text=True)
    if done.returncode != expect:
        raise SystemExit(f"m3c2 {' '.join(map(str, args))}: exit status {done.returncode}, expected {expect}\n"
                         f"{done.stderr}")
    return done


def planes(z: float, n: int = 20_000) -> np.ndarray:
    xy = np.random.default_rng(7).uniform(0.0, 20.0, (n, 2))
    return np.c_[xy, np.full(n, z)]


def main() -> int:
    import m3c2kit
    from m3c2kit.base import portable
    print(f"m3c2kit {m3c2kit.__version__}, Python {sys.version.split()[0]} on {sys.platform}")
    print(f"portability layer: {portable.CAPS}")

    r = m3c2kit.compare(planes(0.0), planes(0.5), core_spacing=2, normal_scale=2, projection_scale=2, max_depth=2)
    ok = np.asarray(r.status) == 0
    assert ok.mean() > 0.9 and np.allclose(np.asarray(r.distance)[ok], 0.5, rtol=0, atol=1e-9), "engine: not 0.5"
    print(f"1. engine: {ok.sum()} core points, every distance 0.5")

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        epochs = []
        for t, z in enumerate((0.0, 0.5, 0.8)):
            epochs.append(folder / f"epoch_{t}.npy")
            np.save(epochs[-1], planes(z))
        out = folder / "change.laz"
        out.write_bytes(b"an older output")
        m3c2("compare", epochs[0], epochs[1], "-o", out, *PARAMS)
        import laspy
        distance = np.asarray(laspy.read(out)["distance"])
        assert np.allclose(distance[np.isfinite(distance)], 0.5, rtol=0, atol=1e-4), "LAZ: not 0.5"
        left = sorted(p.name for p in folder.iterdir() if p.name.startswith(".m3c2"))
        assert not left, f"left behind: {left}"
        print(f"2. atomic writer: {out.name} replaced whole ({len(distance)} points), nothing left beside it")

        try:
            import zarr  # noqa: F401
        except ImportError:
            print("3. series: skipped (no series extra)")
            return 0
        from m3c2kit.series import lock
        store = folder / "store.zarr"
        m3c2("series", *epochs[:2], "-o", store, *PARAMS)
        held = lock.acquire(store, "wheel-smoke")
        try:
            refused = m3c2("series", "add", store, epochs[2], "--quiet", expect=1)
            assert "another m3c2 is writing this store" in refused.stderr and "wheel-smoke" in refused.stderr, \
                refused.stderr
        finally:
            held.release()
        m3c2("series", "add", store, epochs[2], "--quiet")
        m3c2("series", "check", store)
        print(f"3. series: a second writer refused while the lock ({lock.lock_name()}) was held, then added")
    return 0


if __name__ == "__main__":
    os.chdir(tempfile.gettempdir())  # never the source tree: the installed wheel is what runs
    sys.exit(main())
