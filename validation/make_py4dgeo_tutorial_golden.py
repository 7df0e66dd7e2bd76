"""Runs tests/data/py4dgeo-tutorial/tutorial.py with py4dgeo itself and stores what it computed.

Usage (py4dgeo installed in the running Python; m3c2kit never depends on it):
    python validation/make_py4dgeo_tutorial_golden.py
writes tests/data/py4dgeo-tutorial/golden.npz, read by tests/python/compat/test_compat_py4dgeo.py.
"""
from __future__ import annotations

import json
import os
import platform
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parents[1] / "tests" / "data" / "py4dgeo-tutorial"
KEYS = ("distances", "lodetection", "spread1", "spread2", "num_samples1", "num_samples2", "normals",
        "ms_distances", "ms_radii", "robust_distances", "corepoints")


def main() -> None:
    import py4dgeo

    py4dgeo.set_num_threads(1)
    cwd = os.getcwd()
    os.chdir(HERE)
    try:
        namespace: dict = {"__name__": "tutorial"}
        exec(compile((HERE / "tutorial.py").read_text(), "tutorial.py", "exec"), namespace)
    finally:
        os.chdir(cwd)
    meta = {"tool": "py4dgeo", "version": py4dgeo.__version__, "numpy": np.__version__,
            "python": platform.python_version(), "machine": platform.machine()}
    np.savez_compressed(HERE / "golden.npz", meta=json.dumps(meta),
                        **{k: np.asarray(namespace[k]) for k in KEYS})
    print(f"wrote {HERE / 'golden.npz'} ({meta})")


if __name__ == "__main__":
    main()
