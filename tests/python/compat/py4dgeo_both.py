"""A py4dgeo user script run both ways: by py4dgeo 1.2.0 in its own Python (PY4DGEO_PYTHON, by
default /tmp/p4d/bin/python: a separate venv, never beside m3c2kit; the test is skipped when it is
absent) and, with only its `import py4dgeo` line changed, by m3c2kit.compat.py4dgeo in this
process. A script reads its inputs from the .npz file `DATA` and leaves its numbers in `out`
(name -> array)."""
from __future__ import annotations

import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

PY4DGEO_PYTHON = Path(os.environ.get("PY4DGEO_PYTHON", "/tmp/p4d/bin/python"))
PY4DGEO_IMPORT = "import py4dgeo\n"
COMPAT_IMPORT = "import m3c2kit.compat.py4dgeo as py4dgeo\n"


def _with_data(script: str, data: Path) -> str:
    assert script.count(PY4DGEO_IMPORT) == 1, "a script imports py4dgeo exactly once"
    return f"DATA = {str(data)!r}\n{script}"


def ours(script: str, data: Path) -> dict:
    """`script` with only its import changed, run here: its `out`."""
    text = _with_data(script, data)
    changed = text.replace(PY4DGEO_IMPORT, COMPAT_IMPORT)
    assert [a for a, b in zip(text.splitlines(), changed.splitlines()) if a != b] == ["import py4dgeo"]
    scope: dict = {"__name__": "script"}
    exec(compile(changed, "script.py", "exec"), scope)
    return {k: np.asarray(v) for k, v in scope["out"].items()}


def theirs(script: str, data: Path) -> dict:
    """`script` run by py4dgeo 1.2.0 in its own Python: its `out` (the test skipped without it)."""
    if not PY4DGEO_PYTHON.exists():
        pytest.skip(f"py4dgeo 1.2.0's Python not found at {PY4DGEO_PYTHON} (set PY4DGEO_PYTHON)")
    saved = data.with_name(data.stem + "_py4dgeo_out.npz")
    text = _with_data(script, data) + f"\nimport numpy as _np\n_np.savez({str(saved)!r}, **out)\n"
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    done = subprocess.run([str(PY4DGEO_PYTHON), "-c", text], capture_output=True, text=True, env=env,
                          cwd=data.parent, timeout=600)
    assert done.returncode == 0, f"py4dgeo's run failed:\n{done.stderr[-3000:]}"
    with np.load(saved) as z:
        return {k: z[k] for k in z.files}
