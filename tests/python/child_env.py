"""Environment for child interpreters started by the tests."""
from __future__ import annotations

import os
from pathlib import Path

import m3c2kit


def child_env(**extra: str) -> dict[str, str]:
    """os.environ with PYTHONPATH leading to the m3c2 this process imported: the installed
    package under CI, the in-tree one (with its built extension) during development. Never the
    source tree by default: without its compiled extension it cannot be imported."""
    package_root = str(Path(m3c2kit.__file__).resolve().parents[1])
    return dict(os.environ, **extra, PYTHONPATH=os.pathsep.join([package_root, os.environ.get("PYTHONPATH", "")]))
