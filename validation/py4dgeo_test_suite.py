"""py4dgeo 1.2.0's own Python test suite, run against m3c2kit.compat.py4dgeo and against py4dgeo.

    .venv/bin/python validation/py4dgeo_test_suite.py                      # mirror snapshot, v1.2.0
    .venv/bin/python validation/py4dgeo_test_suite.py --tests /path/to/py4dgeo-checkout
    .venv/bin/python validation/py4dgeo_test_suite.py --no-markdown --keep

At run time, into a temporary folder (nothing of py4dgeo's is kept in this repository):

* py4dgeo's ``tests/python`` (its ``conftest.py`` and ``helpers.py`` included) and its package's
  source (read only to list the names each py4dgeo module defines) from the git snapshot
  (``--tests``: a git directory, ``--ref``: the tag) or from a checkout folder;
* a shim package named ``py4dgeo``, first on ``sys.path`` of the compat run, whose modules
  (``py4dgeo``, ``py4dgeo.util``, ``py4dgeo.epoch``, ``py4dgeo.m3c2``, ...: every module py4dgeo
  1.2.0 has) re-export ``m3c2kit.compat.py4dgeo``: a name of py4dgeo module ``py4dgeo.X`` is taken
  from ``m3c2kit.compat.py4dgeo.X`` when that module exists and exports it, else from
  ``m3c2kit.compat.py4dgeo`` itself. A py4dgeo name the compat lacks is a placeholder that raises
  ``NotProvidedByCompat`` (naming it and the compat's ``NOT_PROVIDED`` advice) the moment it is
  called, subclassed, used in ``isinstance`` or has an attribute read: it is never faked, but a
  module that only imports it (py4dgeo's ``conftest.py`` imports ``SpatiotemporalAnalysis``)
  still loads, so each test shows its own result. Names py4dgeo's modules import from other
  libraries (``np``, ``os``, ``laspy``; tests get them through ``from py4dgeo.m3c2 import *``) are
  those libraries' own objects. ``_py4dgeo`` (py4dgeo's C++ module) is not provided at all.

py4dgeo's ``conftest.py`` is used as it is but for one line: its
``from py4dgeo.util import MemoryPolicy, set_memory_policy, download_test_data, find_file`` reads
those four names from the harness (``_p4d_harness``), the same for both runs, because

* ``download_test_data`` needs the network (py4dgeo's own suite errors on every test offline:
  the first part of the output, "as is", shows it): the harness's downloads nothing;
* ``find_file`` then finds only what the harness has: py4dgeo's synthetic plane pair
  ``plane_horizontal_t1.xyz`` / ``_t2.xyz`` (taken from the snapshot's history, py4dgeo's
  ``tests/data`` at 0380c3ff, before the data moved to Zenodo) and whatever ``--data-dir`` holds;
  any other file raises ``FileNotFoundError`` ("needs downloaded data");
* the autouse fixture resetting py4dgeo's memory policy before each test calls
  ``set_memory_policy(MemoryPolicy.COREPOINTS)``: the py4dgeo run gets py4dgeo's own two names;
  the compat run gets the compat's where it provides them, else a no-op for this fixture only
  (m3c2kit has no memory policy; the tests that use the policy themselves still get the
  placeholder from the shim and fail with ``NotProvidedByCompat``).

Both runs use pytest with the same test files and data: the py4dgeo run with ``--py4dgeo-python``
(py4dgeo 1.2.0 installed; pytest too), the compat run with ``--compat-python`` and
``PYTHONPATH=python`` (m3c2kit from this checkout, never py4dgeo). ``--test-deps`` is a folder
added to both runs' ``PYTHONPATH`` for py4dgeo's test-only requirement ``ruptures``
(``pip install --no-deps --target /tmp/p4d-testdeps ruptures``); without it
``test_segmentation.py`` fails to import on both sides.

Prints a table, one row per test: py4dgeo's result, the compat's, and why they differ (the
categories below; a row's reason is checked against the compat's actual error, so a note that no
longer applies shows as "needs review"). Writes it as markdown to
docs/validation/py4dgeo_test_suite.md (``--markdown PATH``; ``--no-markdown``). Asserts nothing.
"""
from __future__ import annotations

import argparse
import ast
import datetime
import io
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import textwrap
from collections import Counter, OrderedDict
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
MIRROR = Path("/work/.mirror/3dgeo-heidelberg+py4dgeo/repo")
DEFAULT_REF = "v1.2.0"
#: py4dgeo's last commit with its test data in git (the files are byte-identical to
#: tests/data/py4dgeo-tutorial/ here).
DATA_COMMIT = "0380c3ffbab8a3cd06db14144171e1281950927f"
DATA_FILES = ("plane_horizontal_t1.xyz", "plane_horizontal_t2.xyz")
LOCAL_DATA = REPO / "tests" / "data" / "py4dgeo-tutorial"
CONFTEST_LINE = "from py4dgeo.util import MemoryPolicy, set_memory_policy, download_test_data, find_file"
ZENODO = "doi:10.5281/zenodo.18378272"

# --------------------------------------------------------------------------------------------
# Files written into the temporary folder
# --------------------------------------------------------------------------------------------

SHIM_CORE = r'''
"""Support of the py4dgeo shim (written by m3c2kit's validation/py4dgeo_test_suite.py)."""
import importlib
import importlib.util
import json
import os
import sys

import m3c2kit.compat.py4dgeo as COMPAT

with open(os.path.join(os.path.dirname(os.path.abspath(__file__)), "_p4d_shim_spec.json")) as _f:
    SPEC = json.load(_f)

#: (module, name, how) of every placeholder touched: the report plugin reads it after each test.
TOUCHED = []


class NotProvidedByCompat(AttributeError):
    """A py4dgeo 1.2.0 name that m3c2kit.compat.py4dgeo does not provide was used."""


class _NotProvidedMeta(type):
    def _fail(cls, how):
        TOUCHED.append((cls._p4d_module, cls._p4d_name, how))
        raise NotProvidedByCompat(cls._p4d_message + f" ({how})")

    def __call__(cls, *args, **kwargs):
        cls._fail("called")

    def __getattr__(cls, attr):
        if attr.startswith("_"):  # Python's and pytest's own probing (__wrapped__, _pytestfixturefunction)
            raise AttributeError(attr)
        cls._fail(f"attribute {attr!r} read")

    def __instancecheck__(cls, instance):
        cls._fail("isinstance")

    def __subclasscheck__(cls, subclass):
        cls._fail("issubclass")

    def __new__(mcs, name, bases, namespace, **kwargs):
        for base in bases:
            if isinstance(base, _NotProvidedMeta) and "_p4d_message" in base.__dict__:
                base._fail(f"subclassed by {name}")
        return super().__new__(mcs, name, bases, namespace, **kwargs)


def placeholder(module, name):
    message = f"py4dgeo's {module}.{name} is not provided by m3c2kit.compat.py4dgeo"
    advice = getattr(COMPAT, "NOT_PROVIDED", {}).get(name)
    if advice:
        message += f"; use instead: {advice}"
    return type.__new__(_NotProvidedMeta, name, (), {"_p4d_module": module, "_p4d_name": name,
                                                   "_p4d_message": message, "__module__": module})


class _MissingModule:
    """A library py4dgeo's module imports that this environment lacks (used only if read)."""

    def __init__(self, name, error):
        self._name, self._error = name, error

    def __getattr__(self, attr):
        if attr.startswith("__"):
            raise AttributeError(attr)
        raise ModuleNotFoundError(f"{self._name} is not installed here ({self._error})")


def compat_lookup(module, name):
    """(value, where) for py4dgeo's module.name, or (None, None) where the compat lacks it."""
    sub = module.split(".", 1)[1] if "." in module else None
    if sub is not None:
        target = f"{COMPAT.__name__}.{sub}"
        if importlib.util.find_spec(target) is not None:
            mod = importlib.import_module(target)
            exported = getattr(mod, "__all__", None)
            if (name in exported) if exported is not None else (hasattr(mod, name) and not name.startswith("_")):
                return getattr(mod, name), target
    try:
        return getattr(COMPAT, name), COMPAT.__name__
    except AttributeError:
        return None, None


def resolve(module, name):
    kind = SPEC[module]["names"][name]
    if kind[0] == "module":                       # import numpy as np
        try:
            importlib.import_module(kind[2])
            return sys.modules[kind[1]]
        except ImportError as error:
            return _MissingModule(kind[2], error)
    if kind[0] == "attr":                         # from scipy.spatial import cKDTree
        try:
            return getattr(importlib.import_module(kind[1]), kind[2])
        except (ImportError, AttributeError) as error:
            return _MissingModule(f"{kind[1]}.{kind[2]}", error)
    if kind[0] == "submodule":                    # import py4dgeo (the shim)
        importlib.import_module(kind[2])
        return sys.modules[kind[1]]
    value, where = compat_lookup(module, name)    # a py4dgeo name
    return placeholder(module, name) if where is None else value


def module_hooks(module):
    names = SPEC[module]["names"]
    this = sys.modules[module]

    def __getattr__(name):
        if name not in names or (name.startswith("__") and name.endswith("__")):
            raise AttributeError(f"module {module!r} (shim of py4dgeo 1.2.0 on m3c2kit.compat.py4dgeo) "
                                 f"has no attribute {name!r}")
        value = resolve(module, name)
        setattr(this, name, value)
        return value

    def __dir__():
        return sorted(set(names) | set(vars(this)))

    public = sorted(n for n in names if not n.startswith("_"))
    return public, __getattr__, __dir__
'''

SHIM_MODULE = '''"""Shim: py4dgeo 1.2.0's {module} on m3c2kit.compat.py4dgeo (validation/py4dgeo_test_suite.py)."""
import _p4d_shim_core as _p4d_core

__all__, __getattr__, __dir__ = _p4d_core.module_hooks(__name__)
'''

HARNESS = r'''
"""The four names py4dgeo's conftest.py reads from py4dgeo.util (validation/py4dgeo_test_suite.py)."""
import os

SIDE = os.environ["P4D_HARNESS_SIDE"]
DATA_DIRS = [d for d in os.environ.get("P4D_HARNESS_DATA", "").split(os.pathsep) if d]


class MissingTestData(FileNotFoundError):
    """A file of py4dgeo's test data archive that this offline run does not have."""


def download_test_data(path=None, filename=None):
    """Offline: nothing is downloaded; find_file looks in the harness's data folders."""
    return DATA_DIRS[0] if DATA_DIRS else None


def find_file(filename, fatal=True):
    if os.path.isabs(filename) and os.path.exists(filename):
        return filename
    for folder in DATA_DIRS:
        for root, _, files in os.walk(folder):
            if filename in files:
                return os.path.join(root, filename)
    if not fatal:
        return filename
    raise MissingTestData(f"needs py4dgeo's downloaded test data: {filename} is in py4dgeo's archive "
                          f"(__ZENODO__), which this offline run does not have")


if SIDE == "py4dgeo":
    from py4dgeo.util import MemoryPolicy, set_memory_policy
else:
    import _p4d_shim_core
    import py4dgeo.util as _util
    MemoryPolicy, set_memory_policy = _util.MemoryPolicy, _util.set_memory_policy
    if isinstance(MemoryPolicy, _p4d_shim_core._NotProvidedMeta) or \
            isinstance(set_memory_policy, _p4d_shim_core._NotProvidedMeta):
        class MemoryPolicy:  # conftest's autouse fixture only: the compat has no memory policy
            COREPOINTS = None

        def set_memory_policy(policy):
            pass
'''.replace("__ZENODO__", ZENODO)

REPORT_PLUGIN = r'''
"""pytest plugin: each test's outcome and exception, as JSON (validation/py4dgeo_test_suite.py)."""
import json
import os
import sys

import pytest

RESULTS = {}
COLLECT = {}


def _touched():
    core = sys.modules.get("_p4d_shim_core")
    return core.TOUCHED if core is not None else None


def _frame(excinfo):
    """The innermost traceback line inside py4dgeo's test files (file:line: source)."""
    found = None
    for entry in excinfo.traceback:
        path = str(entry.path)
        if "/tests/python/" in path.replace(os.sep, "/"):
            try:
                source = str(entry.statement).strip().splitlines()[0]
            except Exception:
                source = ""
            found = f"{os.path.basename(path)}:{entry.lineno + 1}: {source}"
    return found


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    entry = RESULTS.setdefault(item.nodeid, {"phases": {}})
    if call.when == "setup":
        touched = _touched()
        entry["touched_before"] = len(touched) if touched is not None else 0
    phase = {"outcome": report.outcome}
    if hasattr(report, "wasxfail"):
        phase["xfail"] = report.wasxfail
    if call.excinfo is not None:
        phase["type"] = call.excinfo.typename
        phase["mro"] = [c.__name__ for c in type(call.excinfo.value).__mro__]
        phase["message"] = str(call.excinfo.value)[:1500]
        phase["where"] = _frame(call.excinfo)
        if report.skipped and isinstance(report.longrepr, tuple):
            phase["message"] = str(report.longrepr[2])[:1500]
    entry["phases"][call.when] = phase
    if call.when == "teardown":
        touched = _touched()
        if touched is not None:
            entry["touched"] = touched[entry.get("touched_before", 0):]


def pytest_collectreport(report):
    if report.failed:
        COLLECT[report.nodeid] = str(report.longrepr)[-3000:]


def pytest_sessionfinish(session):
    with open(os.environ["P4D_HARNESS_REPORT"], "w") as f:
        json.dump({"tests": RESULTS, "collect_errors": COLLECT}, f, indent=1, default=str)
'''

PYTEST_INI = """[pytest]
# py4dgeo 1.2.0's own filterwarnings (its pyproject.toml)
filterwarnings =
    ignore:The localize method is no longer necessary, as this time zone supports the fold attribute
    ignore:distutils Version classes are deprecated. Use packaging.version instead.
"""

# --------------------------------------------------------------------------------------------
# Reading py4dgeo's sources
# --------------------------------------------------------------------------------------------


def git(gitdir: Path, *args: str, binary: bool = False):
    out = subprocess.run(["git", "--git-dir", str(gitdir), *args], check=True, capture_output=True)
    return out.stdout if binary else out.stdout.decode()


class Source:
    """py4dgeo's files, from a git directory at a ref or from a checkout folder."""

    def __init__(self, where: Path, ref: str):
        self.where, self.ref = where, ref
        self.gitdir = None
        if (where / "HEAD").is_file() and (where / "objects").is_dir():
            self.gitdir = where
        elif (where / ".git").exists() and not (where / "tests" / "python").is_dir():
            self.gitdir = where / ".git"
        if self.gitdir is None and not (where / "tests" / "python").is_dir():
            raise SystemExit(f"{where}: neither a git directory nor a py4dgeo checkout with tests/python")

    def describe(self) -> str:
        if self.gitdir is not None:
            commit = git(self.gitdir, "rev-parse", f"{self.ref}^{{commit}}").strip()
            return f"{self.where} at {self.ref} ({commit[:12]})"
        return f"{self.where} (a checkout folder)"

    def files(self, prefix: str) -> list[str]:
        if self.gitdir is not None:
            return git(self.gitdir, "ls-tree", "-r", "--name-only", self.ref, prefix).split()
        base = self.where
        if not (base / prefix).is_dir():
            return []
        return sorted(str(p.relative_to(base)) for p in (base / prefix).rglob("*") if p.is_file())

    def read(self, path: str, ref: str | None = None) -> bytes:
        if self.gitdir is not None:
            return git(self.gitdir, "show", f"{ref or self.ref}:{path}", binary=True)
        return (self.where / path).read_bytes()

    def extract_tests(self, dest: Path) -> list[str]:
        names = [f for f in self.files("tests/python") if f.endswith(".py")]
        for name in names:
            target = dest / name
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(self.read(name))
        return names

    def data_file(self, name: str) -> bytes | None:
        if self.gitdir is not None:
            try:
                return git(self.gitdir, "show", f"{DATA_COMMIT}:tests/data/{name}", binary=True)
            except subprocess.CalledProcessError:
                return None
        path = self.where / "tests" / "data" / name
        return path.read_bytes() if path.is_file() else None


def module_names(tree: ast.Module, module: str, sources: dict[str, ast.Module]) -> dict[str, list]:
    """Every name a py4dgeo module binds at its top level, and what it is:
    ["py4dgeo"] (defined by py4dgeo or imported from py4dgeo / _py4dgeo: looked up in the compat),
    ["module", bound, full] / ["attr", module, name] (another library's), ["submodule", bound, full]."""
    names: dict[str, list] = {}
    package = module if module == "py4dgeo" else module.rsplit(".", 1)[0]

    fallback = [False]  # inside `except ImportError:` an import's fallback does not replace the import

    def bind(name, kind):
        if fallback[0] and name in names:
            return
        names[name] = kind

    def bind_targets(target):
        if isinstance(target, ast.Name):
            bind(target.id, ["py4dgeo"])
        elif isinstance(target, (ast.Tuple, ast.List)):
            for element in target.elts:
                bind_targets(element)

    def visit(body):
        for node in body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                bind(node.name, ["py4dgeo"])
            elif isinstance(node, ast.Assign):
                for target in node.targets:
                    bind_targets(target)
            elif isinstance(node, (ast.AnnAssign, ast.AugAssign)):
                bind_targets(node.target)
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    top = alias.name.split(".")[0]
                    bound = alias.asname or top
                    full = alias.name
                    if top == "py4dgeo":
                        bind(bound, ["submodule", alias.name if alias.asname else top, full])
                    elif top == "_py4dgeo":
                        bind(bound, ["py4dgeo"])
                    else:
                        bind(bound, ["module", full if alias.asname else top, full])
            elif isinstance(node, ast.ImportFrom):
                source = node.module or ""
                if node.level:
                    source = ".".join([package] + ([source] if source else []))
                ours = source == "py4dgeo" or source.startswith("py4dgeo.") or source == "_py4dgeo"
                for alias in node.names:
                    if alias.name == "*":
                        if source in sources:
                            for name, kind in module_names(sources[source], source, sources).items():
                                if not name.startswith("_"):
                                    names.setdefault(name, kind)
                        continue
                    bound = alias.asname or alias.name
                    if ours and f"{source}.{alias.name}" in sources:
                        bind(bound, ["submodule", f"{source}.{alias.name}", f"{source}.{alias.name}"])
                    elif ours:
                        bind(bound, ["py4dgeo"])
                    else:
                        bind(bound, ["attr", source, alias.name])
            elif isinstance(node, ast.If):
                visit(node.body)
                visit(node.orelse)
            elif isinstance(node, ast.Try):
                visit(node.body)
                for handler in node.handlers:
                    fallback[0] = True
                    visit(handler.body)
                    fallback[0] = False
                visit(node.orelse)
                visit(node.finalbody)
            elif isinstance(node, ast.With):
                visit(node.body)

    visit(tree.body)
    return names


def shim_spec(source: Source) -> dict:
    files = [f for f in source.files("src/py4dgeo") if f.endswith(".py")]
    if not any(f.endswith("src/py4dgeo/__init__.py") for f in files):
        raise SystemExit(f"{source.describe()}: no src/py4dgeo/__init__.py (py4dgeo's package source lists "
                         f"the names the shim provides)")
    trees = {}
    for path in files:
        stem = Path(path).stem
        module = "py4dgeo" if stem == "__init__" else f"py4dgeo.{stem}"
        trees[module] = ast.parse(source.read(path).decode("utf-8-sig"), filename=path)
    spec = {}
    for module, tree in trees.items():
        names = module_names(tree, module, trees)
        if module == "py4dgeo":
            for other in trees:
                if other != "py4dgeo":
                    names.setdefault(other.split(".", 1)[1], ["submodule", other, other])
        spec[module] = {"names": names}
    return spec


def write_shim(spec: dict, shim_dir: Path) -> None:
    package = shim_dir / "py4dgeo"
    package.mkdir(parents=True)
    for module in spec:
        path = package / ("__init__.py" if module == "py4dgeo" else module.split(".", 1)[1] + ".py")
        path.write_text(SHIM_MODULE.format(module=module))
    (shim_dir / "_p4d_shim_core.py").write_text(SHIM_CORE)
    (shim_dir / "_p4d_shim_spec.json").write_text(json.dumps(spec, indent=1, sort_keys=True))


# --------------------------------------------------------------------------------------------
# Running
# --------------------------------------------------------------------------------------------


def run_side(side: str, python: str, run_dir: Path, paths: list[Path], data_dirs: list[Path],
             report: Path, timeout: int, extra_env: dict | None = None) -> dict:
    env = dict(os.environ)
    for key in ("PYTHONPATH", "PYTHONHOME", "PYTHONSTARTUP", "PYTEST_ADDOPTS", "PYTEST_PLUGINS"):
        env.pop(key, None)
    env.update({"PYTHONPATH": os.pathsep.join(str(p) for p in paths), "P4D_HARNESS_SIDE": side,
                "P4D_HARNESS_DATA": os.pathsep.join(str(d) for d in data_dirs),
                "P4D_HARNESS_REPORT": str(report), "MPLBACKEND": "Agg", "PYTHONDONTWRITEBYTECODE": "1"})
    env.update(extra_env or {})
    command = [python, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "_p4d_report",
               "--continue-on-collection-errors", "-o", "console_output_style=classic", "tests/python"]
    try:
        done = subprocess.run(command, cwd=run_dir, env=env, capture_output=True, text=True, timeout=timeout)
        tail = (done.stdout + done.stderr)[-4000:]
        rc = done.returncode
    except subprocess.TimeoutExpired as error:
        tail, rc = f"timed out after {timeout} s: {error}", None
    data = json.loads(report.read_text()) if report.exists() else {"tests": {}, "collect_errors": {}}
    data["rc"], data["tail"] = rc, tail
    return data


def outcome_of(entry: dict) -> tuple[str, dict | None]:
    """('passed' | 'failed' | 'error' | 'skipped' | 'xfailed', the phase that decided it)."""
    phases = entry["phases"]
    setup, call, teardown = phases.get("setup"), phases.get("call"), phases.get("teardown")
    if setup and setup["outcome"] == "failed":
        return "error", setup
    if setup and setup["outcome"] == "skipped":
        return "skipped", setup
    if call:
        if call.get("xfail") is not None:
            return "xfailed", call
        if call["outcome"] == "failed":
            return "failed", call
        if call["outcome"] == "skipped":
            return "skipped", call
    if teardown and teardown["outcome"] == "failed":
        return "error", teardown
    return "passed", None


def short(nodeid: str) -> str:
    return nodeid.replace("tests/python/", "", 1)


def results_of(run: dict) -> dict[str, dict]:
    """test id -> {"outcome", "phase", "touched"}; a module that failed to import gives its tests
    (known from the other side) the collection error."""
    out = {}
    for nodeid, entry in run["tests"].items():
        outcome, phase = outcome_of(entry)
        out[short(nodeid)] = {"outcome": outcome, "phase": phase, "touched": entry.get("touched") or []}
    return out


def collection_error(run: dict, test_id: str) -> dict | None:
    module = test_id.split("::")[0]
    for nodeid, text in run["collect_errors"].items():
        if short(nodeid) == module:
            last = [line for line in text.splitlines() if line.startswith("E ")]
            message = last[-1][1:].strip() if last else text.strip().splitlines()[-1]
            kind, _, rest = message.partition(": ")
            kind = kind.rsplit(".", 1)[-1]
            return {"outcome": "error", "phase": {"type": kind, "message": rest or message, "where": "collection",
                                                  "mro": [kind]}, "touched": [], "collection": True}
    return None


# --------------------------------------------------------------------------------------------
# Why a test differs
# --------------------------------------------------------------------------------------------

CAT_PASS = "passes on both"
CAT_DATA = "needs downloaded data"
CAT_PRIVATE = "py4dgeo internal/private API"
CAT_NAME = "name not provided"
CAT_DESIGN = "different by design"
CAT_BUG = "compat bug"
CAT_QUIRK = "py4dgeo quirk, not reproduced"
CAT_REVIEW = "needs review"
CAT_P4D = "fails on py4dgeo too"
CATEGORY_ORDER = (CAT_PASS, CAT_DATA, CAT_NAME, CAT_PRIVATE, CAT_DESIGN, CAT_QUIRK, CAT_BUG, CAT_P4D, CAT_REVIEW)

#: Reasons that need a reading of the test (automatic rules cannot tell design from defect). Each
#: applies only while the compat's failure still matches `match` (a regular expression searched in
#: "Type: message | test-file line"); otherwise the row says "needs review".
NOTES: list[dict] = [
    {"test": r"test_epoch\.py::(test_epoch_metadata_setters\[25\. November 1986\]|test_normalize_timestamp)",
     "match": r"was not understood", "category": CAT_DESIGN,
     "reason": "free-text timestamp ('25. November 1986', 'February 3rd, 2010, 9:27AM'): py4dgeo reads free "
               "text through dateparser; the compat reads a datetime, a date, (year, day of year) or ISO 8601 "
               "text and refuses the rest with a Py4DGeoError saying so (docs/python.md, the Epoch row)"},
    {"test": r"test_segmentation\.py::test_(construct_from_epochs|construct_from_scratch|access_unassigned_properties)",
     "match": r"was not understood", "category": CAT_DESIGN, "unless_provided": "SpatiotemporalAnalysis",
     "reason": "stops at the free-text timestamp 'March 9th 2022, 16:32' / '16:33' (dateparser; "
               "docs/python.md, the Epoch row); the test also needs SpatiotemporalAnalysis"},
    {"test": r"test_epoch\.py::test_read_from_xyz_more_columns", "match": r"DID NOT RAISE", "category": CAT_QUIRK,
     "reason": "the file is one line '0 0 0 1 2 3'. py4dgeo refuses any one-line XYZ file, whatever its "
               "column count ('Clouds need to be an array of shape nx3': numpy.genfromtxt gives one row as a "
               "1-D array) and reads six columns from a two-line file; the compat reads the one point "
               "(not stated in docs/python.md)"},
    {"test": r"test_epoch\.py::test_cpp_props_not_interchangeable", "match": r"^AttributeError: property 'cloud'",
     "category": CAT_BUG,
     "reason": "`epoch.cloud = 42`: py4dgeo raises Py4DGeoError ('The Epoch point cloud cannot be changed "
               "after initialization...'); the compat raises a bare AttributeError (a property without a "
               "setter), which `except Py4DGeoError` does not catch. (`epoch.kdtree = None`, the test's "
               "second check, would then be accepted silently: the compat's Epoch has no kdtree)"},
    {"test": r"test_(kdtree|octree)\.py::.*|test_epoch\.py::test_epoch_pickle",
     "match": r"'Epoch' object has no attribute '(kdtree|octree)'", "category": CAT_NAME,
     "reason": "Epoch.kdtree / Epoch.octree, py4dgeo's search trees (SearchTree in the compat's NOT_PROVIDED: "
               "m3c2kit builds its index in every run; Epoch.build_kdtree/build_octree are accepted and do "
               "nothing)"},
    {"test": r"test_logger\.py::.*", "match": r"assert not True.*os\.path\.exists\(filename\)", "category": CAT_BUG,
     "reason": "set_py4dgeo_logfile(f) creates f at once (logging.FileHandler without delay); py4dgeo's "
               "creates it at the first record (FileHandler(filename, mode='a', delay=True)), and the test "
               "asserts that the file does not exist right after the call"},
    {"test": r"test_m3c2\.py::test_m3c2\[(True|False)\]", "match": r"DID NOT RAISE Py4DGeoError.*test_m3c2\.py:11",
     "category": CAT_BUG,
     "reason": "M3C2(epochs=(epoch1,), ...): py4dgeo raises Py4DGeoError('Exactly two epochs need to be "
               "given!') in the constructor (its epochs setter); the compat accepts the one epoch and raises "
               "only in run() ('M3C2: epochs must be a pair')"},
    {"test": r"test_registration\.py::test_(icp|stable_area_icp)", "match": r"unobservable", "category": CAT_DESIGN,
     "reason": "the fixture's epochs are a flat plane; m3c2kit's ICP refuses a registration whose motion the "
               "data cannot constrain (the shifts along the plane, the rotation about its normal), naming it "
               "(docs/registration.md, step 6 'Observability'); py4dgeo returns a 4x4 matrix whatever the "
               "conditioning, which is all the test checks"},
]


def describe(result: dict | None) -> str:
    if result is None:
        return "not run"
    phase = result.get("phase")
    if result["outcome"] in ("passed",) or phase is None:
        return result["outcome"]
    where = " at collection" if result.get("collection") else (" in setup" if result["outcome"] == "error" else "")
    return f"{result['outcome']}{where}"


def signature(result: dict) -> str:
    phase = result.get("phase") or {}
    return f"{phase.get('type', '')}: {first_line(phase.get('message', ''))} | {phase.get('where') or ''}"


def classify(test_id: str, p4d: dict | None, compat: dict | None, provided: set[str] = frozenset()) -> tuple[str, str]:
    """(category, reason) for one test; `provided`: the top-level py4dgeo names the compat provides."""
    category, reason = _classify(test_id, p4d, compat)
    note = getattr(reason, "note", None)
    if note and note.get("unless_provided"):
        name = note["unless_provided"]
        if name not in provided:
            return CAT_NAME, f"{name} (not provided); {reason}"
        return category, f"{reason} ({name} is provided)"
    return category, str(reason)


class _NoteReason(str):
    note: dict


def _noted(note: dict) -> tuple[str, str]:
    reason = _NoteReason(note["reason"])
    reason.note = note
    return note["category"], reason


def _classify(test_id: str, p4d: dict | None, compat: dict | None) -> tuple[str, str]:
    p_out = p4d["outcome"] if p4d else "not run"
    c_out = compat["outcome"] if compat else "not run"
    c_sig = signature(compat) if compat else ""
    p_sig = signature(p4d) if p4d else ""
    c_phase = (compat or {}).get("phase") or {}

    if p_out == "passed" and c_out == "passed":
        touched = compat.get("touched") if compat else None
        if touched:
            return CAT_REVIEW, f"passed, but touched names the compat does not provide: {touched}"
        return CAT_PASS, ""
    p_phase = (p4d or {}).get("phase") or {}
    if "MissingTestData" in p_phase.get("mro", []):
        files = re.findall(r"data: (\S+) is in", p_sig)
        extra = ""
        if c_out != "passed" and "MissingTestData" not in c_phase.get("mro", []):
            extra = f"; the compat stops earlier: {c_phase.get('type')}: {first_line(c_phase.get('message', ''))}"
        return CAT_DATA, f"{', '.join(files) or 'a data file'} (py4dgeo's archive, {ZENODO}){extra}"
    if p_out not in ("passed",) and c_out not in ("passed",):
        note = match_note(test_id, c_sig)
        if note:
            return _noted(note)
        if p_out == "skipped" and "NotProvidedByCompat" in c_phase.get("mro", []):
            return CAT_NAME, (f"{not_provided_reason(c_phase.get('message', ''))}; py4dgeo skipped it: "
                              f"{first_line(p4d['phase'].get('message', ''))}")
        return CAT_P4D, f"py4dgeo: {first_line(p_sig)}; compat: {first_line(c_sig)}"
    if c_out == "passed":
        note = match_note(test_id, "passed")
        if note:
            return _noted(note)
        return CAT_REVIEW, f"passes on the compat only; py4dgeo: {first_line(p_sig)}"
    # py4dgeo passes, the compat does not
    note = match_note(test_id, c_sig)
    if note:
        return _noted(note)
    mro = c_phase.get("mro", [])
    message = c_phase.get("message", "")
    if "NotProvidedByCompat" in mro:
        return CAT_NAME, not_provided_reason(message)
    if compat and compat.get("collection") and "_py4dgeo" in message:
        return CAT_PRIVATE, "imports _py4dgeo, py4dgeo's C++ module"
    if c_phase.get("type") == "ModuleNotFoundError" and "_py4dgeo" in message:
        return CAT_PRIVATE, "imports _py4dgeo, py4dgeo's C++ module"
    missing = re.search(r"'(\w+)' object has no attribute '(\w+)'", message)
    if c_phase.get("type") == "AttributeError" and missing and missing.group(2).startswith("_"):
        return CAT_PRIVATE, f"{missing.group(1)}.{missing.group(2)} (a private attribute of py4dgeo's object)"
    if c_phase.get("type") == "AttributeError" and missing:
        return CAT_NAME, f"{missing.group(1)}.{missing.group(2)} (a py4dgeo attribute the compat's object lacks)"
    return CAT_REVIEW, first_line(c_sig)


def not_provided_reason(message: str) -> str:
    name = re.search(r"py4dgeo's (\S+) is not provided", message)
    listed = "listed in the compat's NOT_PROVIDED" if "; use instead:" in message else \
        "not in the compat's NOT_PROVIDED list"
    return f"{name.group(1) if name else first_line(message)} ({listed})"


def first_line(text: str) -> str:
    text = (text or "").strip()
    return text.splitlines()[0][:300] if text else ""


def match_note(test_id: str, compat_signature: str) -> dict | None:
    for note in NOTES:
        if re.fullmatch(note["test"], test_id) and re.search(note["match"], compat_signature, re.S):
            return note
    return None


# --------------------------------------------------------------------------------------------
# Versions and output
# --------------------------------------------------------------------------------------------


def version_of(python: str, paths: list[Path], code: str) -> str:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(str(p) for p in paths))
    try:
        return subprocess.run([python, "-c", code], capture_output=True, text=True, env=env,
                              timeout=120).stdout.strip() or "?"
    except Exception as error:  # a version is informative only
        return f"? ({error})"


VERSION_CODE = textwrap.dedent("""
    import platform, importlib.metadata as md
    def v(name):
        try:
            return md.version(name)
        except Exception:
            return "-"
    try:
        import ruptures
        rup = ruptures.__version__
    except Exception:
        rup = "-"
    print(f"Python {platform.python_version()}, pytest {v('pytest')}, numpy {v('numpy')}, "
          f"laspy {v('laspy')}, ruptures {rup}", end="")
    try:
        import py4dgeo, sys
        print(f", py4dgeo {v('py4dgeo')} ({py4dgeo.__file__})", end="")
    except Exception:
        pass
    try:
        import m3c2kit
        print(f", m3c2kit {m3c2kit.__version__} ({m3c2kit.__file__})", end="")
    except Exception:
        pass
""")


def repo_state() -> str:
    try:
        head = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short=12", "HEAD"], capture_output=True,
                              text=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(REPO), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True).stdout.strip()
        return f"{head}{' with uncommitted changes' if dirty else ''}"
    except Exception:
        return "?"


def md_escape(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def name_map(spec: dict, compat_python: str, paths: list[Path]) -> dict:
    """py4dgeo module -> {"provided": {name: where}, "missing": [names]}, as the shim resolves them."""
    code = textwrap.dedent("""
        import json, _p4d_shim_core as core
        out = {}
        for module, entry in core.SPEC.items():
            provided, missing = {}, []
            for name, kind in sorted(entry["names"].items()):
                if kind[0] != "py4dgeo" or name.startswith("_"):
                    continue
                value, where = core.compat_lookup(module, name)
                if where is None:
                    missing.append(name)
                else:
                    provided[name] = where
            out[module] = {"provided": provided, "missing": missing}
        print(json.dumps(out))
    """)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(str(p) for p in paths))
    done = subprocess.run([compat_python, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    if done.returncode != 0:
        return {"error": done.stderr[-2000:]}
    return json.loads(done.stdout)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tests", type=Path, default=MIRROR,
                        help="py4dgeo's git directory (bare or not) or a checkout folder (default: %(default)s)")
    parser.add_argument("--ref", default=DEFAULT_REF, help="the tag or commit in a git directory (%(default)s)")
    parser.add_argument("--py4dgeo-python", default="/tmp/p4d/bin/python",
                        help="a Python with py4dgeo 1.2.0 and pytest (%(default)s)")
    parser.add_argument("--compat-python", default=str(REPO / ".venv" / "bin" / "python"),
                        help="the development environment's Python (%(default)s), run with PYTHONPATH=python")
    parser.add_argument("--data-dir", type=Path, action="append", default=[],
                        help="a folder with py4dgeo's test data (e.g. its extracted archive); repeatable")
    parser.add_argument("--test-deps", type=Path, default=Path("/tmp/p4d-testdeps"),
                        help="folder with py4dgeo's test requirement ruptures, added to both runs' PYTHONPATH "
                             "when it exists (%(default)s)")
    parser.add_argument("--markdown", type=Path, default=REPO / "docs" / "validation" / "py4dgeo_test_suite.md")
    parser.add_argument("--no-markdown", action="store_true")
    parser.add_argument("--skip-as-is", action="store_true",
                        help="skip the two runs with py4dgeo's conftest.py unchanged")
    parser.add_argument("--timeout", type=int, default=1800, help="seconds per pytest run (%(default)s)")
    parser.add_argument("--keep", action="store_true", help="keep the temporary folder and print its path")
    parser.add_argument("--json", type=Path, help="also write the rows as JSON here")
    args = parser.parse_args(argv)

    source = Source(args.tests, args.ref)
    tmp = Path(tempfile.mkdtemp(prefix="p4d-suite-"))
    try:
        return run_all(args, source, tmp)
    finally:
        if args.keep:
            print(f"\ntemporary folder kept: {tmp}")
        else:
            shutil.rmtree(tmp, ignore_errors=True)


def prepare_run_dir(run_dir: Path, source: Source, patch_conftest: bool) -> None:
    run_dir.mkdir(parents=True)
    source.extract_tests(run_dir)
    (run_dir / "pytest.ini").write_text(PYTEST_INI)
    if patch_conftest:
        conftest = run_dir / "tests" / "python" / "conftest.py"
        text = conftest.read_text()
        if text.count(CONFTEST_LINE) != 1:
            raise SystemExit(f"py4dgeo's conftest.py no longer has the line the harness replaces:\n  {CONFTEST_LINE}")
        conftest.write_text(text.replace(CONFTEST_LINE, CONFTEST_LINE.replace("py4dgeo.util", "_p4d_harness")))


def run_all(args, source: Source, tmp: Path) -> int:
    started = datetime.datetime.now(datetime.timezone.utc)
    support, shim, data = tmp / "support", tmp / "shim", tmp / "data"
    support.mkdir()
    data.mkdir()
    (support / "_p4d_harness.py").write_text(HARNESS)
    (support / "_p4d_report.py").write_text(REPORT_PLUGIN)
    spec = shim_spec(source)
    write_shim(spec, shim)

    # the data the harness has: py4dgeo's plane pair from the snapshot's history (or this repo's copy)
    data_notes = []
    for name in DATA_FILES:
        blob = source.data_file(name)
        origin = f"py4dgeo's tests/data at {DATA_COMMIT[:8]}"
        if blob is None and (LOCAL_DATA / name).is_file():
            blob, origin = (LOCAL_DATA / name).read_bytes(), str((LOCAL_DATA / name).relative_to(REPO))
        if blob is not None:
            (data / name).write_bytes(blob)
            data_notes.append(f"{name} ({origin})")
    data_dirs = [data] + [d.resolve() for d in args.data_dir]
    deps = [args.test_deps.resolve()] if args.test_deps and args.test_deps.is_dir() else []

    p4d_paths = [support] + deps
    compat_paths = [shim, support, REPO / "python"] + deps
    # the compat run must not reach a real py4dgeo: the shim is first; make sure nothing else provides _py4dgeo
    check = version_of(args.compat_python, compat_paths,
                       "import importlib.util as u, py4dgeo; print(py4dgeo.__file__, u.find_spec('_py4dgeo'))")
    if not check.startswith(str(shim)) or not check.endswith("None"):
        raise SystemExit(f"the compat run would not use the shim alone: {check}")

    runs = {}
    as_is = {}
    if not args.skip_as_is:
        for side, python, paths in (("py4dgeo", args.py4dgeo_python, [support] + deps),
                                    ("compat", args.compat_python, compat_paths)):
            run_dir = tmp / f"as-is-{side}"
            prepare_run_dir(run_dir, source, patch_conftest=False)
            print(f"[as is] running py4dgeo's suite, conftest.py unchanged, with {side} ...", flush=True)
            as_is[side] = run_side(side, python, run_dir, paths, data_dirs, tmp / f"as-is-{side}.json",
                                   args.timeout)
    for side, python, paths in (("py4dgeo", args.py4dgeo_python, p4d_paths),
                                ("compat", args.compat_python, compat_paths)):
        run_dir = tmp / f"run-{side}"
        prepare_run_dir(run_dir, source, patch_conftest=True)
        print(f"running py4dgeo's suite with {side} ...", flush=True)
        runs[side] = run_side(side, python, run_dir, paths, data_dirs, tmp / f"{side}.json", args.timeout)

    names = name_map(spec, args.compat_python, compat_paths)
    provided = set((names.get("py4dgeo") or {}).get("provided", {})) if "error" not in names else set()
    p4d, compat = results_of(runs["py4dgeo"]), results_of(runs["compat"])
    ids = list(OrderedDict.fromkeys(list(p4d) + list(compat)))
    rows = []
    for test_id in ids:
        p = p4d.get(test_id) or collection_error(runs["py4dgeo"], test_id)
        c = compat.get(test_id) or collection_error(runs["compat"], test_id)
        category, reason = classify(test_id, p, c, provided)
        rows.append({"test": test_id, "py4dgeo": describe(p), "compat": describe(c), "category": category,
                     "reason": reason, "py4dgeo_error": signature(p) if p and p["outcome"] != "passed" else "",
                     "compat_error": signature(c) if c and c["outcome"] != "passed" else ""})

    versions = {"py4dgeo side": version_of(args.py4dgeo_python, p4d_paths, VERSION_CODE),
                "compat side": version_of(args.compat_python, [REPO / "python"] + deps, VERSION_CODE)}
    info = {"date": started.strftime("%Y-%m-%d %H:%M UTC"), "source": source.describe(),
            "m3c2kit": f"{REPO} at {repo_state()}", "versions": versions, "data": data_notes,
            "deps": [str(d) for d in deps], "as_is": as_is, "runs": runs, "names": names,
            "argv": sys.argv[1:]}

    print_table(rows, info)
    if args.json:
        kept = {k: v for k, v in info.items() if k not in ("runs", "as_is")}
        args.json.write_text(json.dumps({"rows": rows, "info": kept}, indent=1, default=str))
    if not args.no_markdown:
        args.markdown.parent.mkdir(parents=True, exist_ok=True)
        args.markdown.write_text(markdown(rows, info))
        print(f"\nwrote {args.markdown}")
    return 0


def as_is_summary(run: dict) -> str:
    counts = Counter(outcome_of(e)[0] for e in run["tests"].values())
    causes = Counter()
    for entry in run["tests"].values():
        outcome, phase = outcome_of(entry)
        if phase and outcome != "passed":
            causes[f"{phase.get('type')}: {first_line(phase.get('message', ''))[:200]}"] += 1
    parts = ", ".join(f"{n} {k}" for k, n in sorted(counts.items()))
    if run["collect_errors"]:
        parts += f", {len(run['collect_errors'])} module(s) not importable"
    top = "; ".join(f"{n} x {k}" for k, n in causes.most_common(2))
    return f"{parts or 'nothing ran'}" + (f" (most: {top})" if top else "")


def counts_by_category(rows):
    return Counter(r["category"] for r in rows)


def print_table(rows, info) -> None:
    width = max(len(r["test"]) for r in rows) if rows else 10
    print(f"\npy4dgeo's test suite ({info['source']}) on py4dgeo and on m3c2kit.compat.py4dgeo, {info['date']}")
    for side, text in info["versions"].items():
        print(f"  {side}: {text}")
    if info["as_is"]:
        for side, run in info["as_is"].items():
            print(f"  as is ({side}): {as_is_summary(run)}")
    print()
    print(f"{'test':<{width}}  {'py4dgeo':<18} {'compat':<22} category: reason")
    for r in rows:
        print(f"{r['test']:<{width}}  {r['py4dgeo']:<18} {r['compat']:<22} {r['category']}"
              + (f": {r['reason']}" if r["reason"] else ""))
    print("\nper category:")
    counts = counts_by_category(rows)
    for category in CATEGORY_ORDER:
        if counts.get(category):
            print(f"  {category}: {counts[category]}")
    print(f"  total: {len(rows)}")


def markdown(rows, info) -> str:
    counts = counts_by_category(rows)
    names = info.get("names") or {}
    out = io.StringIO()
    w = out.write
    w("# py4dgeo 1.2.0's own test suite on m3c2kit.compat.py4dgeo\n\n")
    w("Generated by `validation/py4dgeo_test_suite.py`; do not edit by hand (rerun it).\n\n")
    w(MD_INTRO.replace("{count}", str(len(rows))))
    w("## Run\n\n")
    w(f"- date: {info['date']}\n")
    w(f"- py4dgeo's tests: {info['source']}\n")
    w(f"- m3c2kit: {info['m3c2kit']}\n")
    for side, text in info["versions"].items():
        w(f"- {side}: {text}\n")
    w(f"- test data the harness has: {', '.join(info['data']) or 'none'}"
      + "".join(f"; {d}" for d in info.get("extra_data", [])) + "\n")
    w(f"- test requirement `ruptures` from: {', '.join(info['deps']) or 'not available'}\n")
    w(f"- command: `.venv/bin/python validation/py4dgeo_test_suite.py {' '.join(info['argv'])}`".rstrip() + "\n\n")
    w(MD_RERUN)
    if info["as_is"]:
        w("## With py4dgeo's conftest.py unchanged\n\n")
        util_missing = (names.get("py4dgeo.util") or {}).get("missing", []) if "error" not in names else []
        four = [n for n in ("download_test_data", "find_file", "MemoryPolicy", "set_memory_policy")
                if n in util_missing]
        w("Offline, py4dgeo's session fixture `ensure_test_data` calls `download_test_data()`, which needs "
          "the network, so on py4dgeo every test errors before it starts; on the compat, "
          + (f"which does not provide {', '.join(f'`{n}`' for n in four)}, " if four else "")
          + "the same fixtures stop them:\n\n")
        for side, run in info["as_is"].items():
            w(f"- {side}: {md_escape(as_is_summary(run))}\n")
        w("\nThe table below is therefore made with conftest.py's one import line of those four names "
          "taken from the harness (top of this page).\n\n")
    w("## Summary\n\n| category | tests |\n|---|---|\n")
    for category in CATEGORY_ORDER:
        if counts.get(category):
            w(f"| {category} | {counts[category]} |\n")
    w(f"| total | {len(rows)} |\n\n")
    w(MD_CATEGORIES)
    for title, category in (("Compat bugs", CAT_BUG), ("Different by design", CAT_DESIGN),
                            ("py4dgeo quirks not reproduced", CAT_QUIRK), ("Needs review", CAT_REVIEW),
                            ("Fails on py4dgeo too", CAT_P4D)):
        chosen = [r for r in rows if r["category"] == category]
        if not chosen:
            continue
        w(f"## {title}\n\n")
        by_reason = OrderedDict()
        for r in chosen:
            by_reason.setdefault(r["reason"], []).append(r)
        for reason, group in by_reason.items():
            tests = ", ".join("`" + md_escape(r["test"]) + "`" for r in group)
            w(f"- {tests}: {md_escape(reason)}\n")
            errors = OrderedDict.fromkeys(r["compat_error"] for r in group if r["compat_error"])
            for error in errors:
                w(f"  - compat: `{md_escape(error)}`\n")
        w("\n")
    w("## Per test\n\n| test | py4dgeo | compat | category | reason |\n|---|---|---|---|---|\n")
    for r in rows:
        w(f"| `{md_escape(r['test'])}` | {r['py4dgeo']} | {r['compat']} | {r['category']} "
          f"| {md_escape(r['reason'])} |\n")
    if names and "error" not in names:
        w("\n## py4dgeo's names, as the shim resolves them\n\n")
        w("Every name a py4dgeo 1.2.0 module defines or imports from py4dgeo (other libraries' names left "
          "out): where the compat provides it (from the compat's module of that name, else from "
          "`m3c2kit.compat.py4dgeo`), or not provided.\n\n"
          "| py4dgeo module | provided (from) | not provided |\n|---|---|---|\n")
        for module, entry in sorted(names.items()):
            provided = ", ".join(f"`{n}`" + ("" if where == "m3c2kit.compat.py4dgeo" else f" ({where.rsplit('.', 1)[1]})")
                                 for n, where in entry["provided"].items())
            w(f"| `{module}` | {provided or '-'} | {', '.join(f'`{n}`' for n in entry['missing']) or '-'} |\n")
    return out.getvalue()


MD_INTRO = """py4dgeo 1.2.0's `tests/python` ({count} tests) is extracted from py4dgeo's git snapshot into a
temporary folder and run twice with pytest: with py4dgeo 1.2.0 itself, and with a shim package
named `py4dgeo` that re-exports `m3c2kit.compat.py4dgeo` (so the tests' own
`import py4dgeo` / `from py4dgeo.m3c2 import *` reach the compat). Nothing of py4dgeo's is kept in
this repository. The shim maps each py4dgeo module `py4dgeo.X` to `m3c2kit.compat.py4dgeo.X` where
that exists, else to `m3c2kit.compat.py4dgeo`; a py4dgeo name the compat lacks is a placeholder
that raises `NotProvidedByCompat` (naming the compat's `NOT_PROVIDED` advice) when used, never a
stand-in; `_py4dgeo`, py4dgeo's C++ module, is not provided.

py4dgeo's `conftest.py` is used unchanged but for one line: the four test-infrastructure names it
imports from `py4dgeo.util` (`download_test_data`, `find_file`, `MemoryPolicy`,
`set_memory_policy`) come from the harness, identically for both runs: no download (there is no
network), `find_file` finds only py4dgeo's synthetic plane pair (`plane_horizontal_t1.xyz`,
`_t2.xyz`, from py4dgeo's own git history), and the autouse fixture that resets py4dgeo's memory
policy is py4dgeo's own on the py4dgeo side and a no-op on the compat side (the compat has no
memory policy; tests that use one still fail on the compat with `NotProvidedByCompat`). Every
other test datum (LAZ files, segmented clouds, `synthetic.zip`, the AHK rock glacier epochs,
`sps.json`, ...) is in py4dgeo's Zenodo archive and is missing on both sides.

72 of the tests are one test, `test_change_point_detection_against_ruptures`, parametrised: it
compares the `ruptures` library with `_py4dgeo.change_point_detection`, py4dgeo's C++ function.

"""

MD_RERUN = """To rerun (py4dgeo 1.2.0 with pytest in `/tmp/p4d`; py4dgeo's test requirement `ruptures`
into a side folder, not into either environment):

```
/tmp/p4d/bin/pip install pytest
/tmp/p4d/bin/pip install --no-deps --target /tmp/p4d-testdeps ruptures
.venv/bin/python validation/py4dgeo_test_suite.py          # --tests DIR, --ref TAG, --data-dir DIR, --keep
```

`--data-dir` adds folders `find_file` searches (py4dgeo's extracted test-data archive, where one
has it): the rows marked "needs downloaded data" then run.

"""

MD_CATEGORIES = """Categories: **passes on both**; **needs downloaded data**: py4dgeo cannot run it offline
either (its data file is only in the Zenodo archive); **name not provided**: the compat lacks a
py4dgeo name the test uses (its `NOT_PROVIDED`, or a name it does not list); **py4dgeo internal/private
API**: the test reaches `_py4dgeo` or a private attribute; **different by design**: the compat
deliberately behaves otherwise, where docs/python.md or the compat's docstrings say so;
**py4dgeo quirk, not reproduced**: the test relies on an accident of py4dgeo's implementation that
the compat does not copy (and its docs do not mention); **compat bug**: a public py4dgeo behaviour
the compat gets wrong (a wrong result, a crash, a wrong error class or moment); **fails on py4dgeo too**;
**needs review**: none of the above was recognised (a changed result: read the row).

"""


if __name__ == "__main__":
    sys.exit(main())
