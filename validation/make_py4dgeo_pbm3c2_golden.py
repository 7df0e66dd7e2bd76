"""Runs tests/data/py4dgeo-pbm3c2/script.py with py4dgeo itself and stores what it computed.

Usage (py4dgeo installed in the running Python; m3c2kit never depends on it):
    python validation/make_py4dgeo_pbm3c2_golden.py
writes tests/data/py4dgeo-pbm3c2/golden.npz, read by tests/python/compat/test_compat_pbm3c2.py.
"""
from __future__ import annotations

import json
import os
import platform
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parents[1] / "tests" / "data" / "py4dgeo-pbm3c2"


def main() -> None:
    import py4dgeo

    cwd = os.getcwd()
    with tempfile.TemporaryDirectory() as folder:
        os.chdir(folder)
        try:
            namespace: dict = {"__name__": "script"}
            exec(compile((HERE / "script.py").read_text(), "script.py", "exec"), namespace)
        finally:
            os.chdir(cwd)
    out = {}
    for name in ("forest", "nearest"):
        frame = namespace[name]
        for column in frame.columns:
            out[f"{name}_{column}"] = frame[column].to_numpy(dtype=np.float64)
    metrics = namespace["metrics"]
    out.update({f"metrics_{c}": metrics[c].to_numpy(dtype=np.float64) for c in metrics.columns})
    out["metrics_segment_id"] = metrics.index.to_numpy(dtype=np.float64)
    meta = {"tool": "py4dgeo", "version": py4dgeo.__version__, "numpy": np.__version__,
            "python": platform.python_version(), "machine": platform.machine()}
    np.savez_compressed(HERE / "golden.npz", meta=json.dumps(meta), **out)
    print(f"wrote {HERE / 'golden.npz'} ({meta})")


if __name__ == "__main__":
    main()
