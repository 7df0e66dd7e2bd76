"""The command line's own process imports laspy without requests and pyproj (m3c2kit.io.laspy_local);
a file's CRS is still read, a programmatic call imports laspy as usual, and a laspy that needs a
hidden module is imported afresh."""
from __future__ import annotations

import importlib.util
import json
import subprocess
import sys

import numpy as np
import pytest

from m3c2kit.io import Cloud, write_cloud_table

pytestmark = pytest.mark.filterwarnings("ignore:.*LAS stores the coordinates")  # the random test clouds

# Runs the `m3c2` command in a fresh interpreter (main() without arguments, as the script does, or
# with them, as a program does), then reports which modules it imported and whether requests
# still imports.
_PROBE = r"""
import json, sys
import m3c2kit.cli.main
argv = {argv!r}
if {as_script!r}:
    sys.argv = ["m3c2", *argv]
    rc = m3c2kit.cli.main.main()
else:
    rc = m3c2kit.cli.main.main(argv)
loaded = {{name: name in sys.modules for name in ("laspy", "pyproj", "requests")}}
import laspy.copc
try:
    import requests
    importable = True
except ImportError:
    importable = False
print(json.dumps({{"rc": rc, **loaded, "requests_importable": importable,
                  "copc_has_requests": laspy.copc.requests is not None}}))
"""


def _probe(argv, as_script=True):
    proc = subprocess.run([sys.executable, "-c", _PROBE.format(argv=[str(a) for a in argv], as_script=as_script)],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout, json.loads(proc.stdout.strip().splitlines()[-1])


def _las(path, crs=None):
    xyz = np.random.default_rng(3).uniform(0, 10, (50, 3)) + [630000, 4830000, 0]
    write_cloud_table(path, xyz, {"d": np.ones(50)}, like=Cloud(xyz, crs=crs))
    return path


def test_the_command_line_imports_laspy_without_requests_or_pyproj(tmp_path):
    out, seen = _probe(["info", _las(tmp_path / "plain.las")])
    assert seen["rc"] == 0 and "50" in out
    assert seen["laspy"] and not seen["pyproj"] and not seen["requests"]
    # Hidden from laspy's import only: requests imports afterwards wherever it is installed.
    assert seen["requests_importable"] == (importlib.util.find_spec("requests") is not None)
    assert not seen["copc_has_requests"]


def test_a_crs_is_still_read_by_the_command_line(tmp_path):
    pytest.importorskip("pyproj")
    from m3c2kit.io import crs as C

    out, seen = _probe(["info", _las(tmp_path / "utm.las", crs=C.assign_crs("EPSG:32617"))])
    assert seen["rc"] == 0 and "EPSG:32617" in out and seen["pyproj"]


def test_a_program_calling_main_imports_laspy_as_usual(tmp_path):
    installed = importlib.util.find_spec("requests") is not None
    _, seen = _probe(["info", _las(tmp_path / "plain.las")], as_script=False)
    assert seen["rc"] == 0 and seen["laspy"]
    assert seen["copc_has_requests"] == installed and seen["requests"] == installed


def test_a_laspy_needing_a_hidden_module_is_imported_afresh():
    script = r"""
import sys
from m3c2kit.io import laspy_local
laspy_local.UNUSED_BY_LOCAL_FILES = ("laspy.header",)  # as if laspy needed a hidden module
laspy_local.import_laspy_for_local_files()
assert not any(m == "laspy" or m.startswith("laspy.") for m in sys.modules), sorted(sys.modules)
import laspy
assert laspy.LasHeader is not None and sys.modules["laspy.header"] is not None
"""
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
