"""What `import m3c2kit` and building the `m3c2` parser import (issue 19, whole process): none
of the heavy optional libraries a compare run does not use, and not laspy (which imports pyproj
and requests) until a LAS file is read. Checked in a fresh interpreter through sys.modules, not
by timing."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

#: Libraries a plain compare run never needs at import time (each costs tens to hundreds of ms).
HEAVY = ("matplotlib", "dask", "distributed", "pyproj", "rasterio", "xarray", "zarr", "plotly", "sklearn",
         "scipy", "tqdm", "laspy", "requests", "pye57")
#: The package's own modules a compare run does not use.
OWN = ("m3c2kit.output.report.figures", "m3c2kit.output.report.view3d", "m3c2kit.output.report.cartography", "m3c2kit.series.epochs",
       "m3c2kit.classify.plot", "m3c2kit.classify.apply", "m3c2kit.classify.model", "m3c2kit.classify.features",
       "m3c2kit.classify.train", "m3c2kit.classify.labels")


def _imported_after(code: str) -> list[str]:
    probe = f"import sys, json\n{code}\nprint(json.dumps(sorted(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def _heavy(modules: list[str], names) -> list[str]:
    return sorted({m for m in modules for h in names if m == h or m.startswith(h + ".")})


def test_import_m3c2kit_imports_no_heavy_library():
    modules = _imported_after("import m3c2kit")
    assert _heavy(modules, HEAVY + OWN) == []
    assert "m3c2kit" in modules and "m3c2kit._core" not in modules  # the public names load on first use
    modules = _imported_after("import m3c2kit\nm3c2kit.compare")
    assert "m3c2kit._core" in modules and _heavy(modules, HEAVY + OWN) == []  # the probe sees imports at all


def test_version_imports_no_library():
    """Issue 45: `m3c2 --version` took 0.29 s, importing every subcommand's modules."""
    modules = _imported_after("from m3c2kit.cli.main import main\nassert main(['--version']) == 0")
    assert "numpy" not in modules and not [m for m in modules if m.startswith("m3c2kit.") and not m.startswith(
        ("m3c2kit.base", "m3c2kit.cli"))], modules


@pytest.mark.parametrize("argv", [["--help"], ["-h"], [], ["comapre"]])
def test_the_top_level_help_imports_no_library(argv):
    """Issue 45: `m3c2 --help` took 0.8 s, building every subcommand's parser (numpy, the engine,
    the series). It lists them from cli/command_index.py; an unknown command too."""
    probe = (f"from m3c2kit.cli.main import main\nimport contextlib, io\n"
             f"with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):\n"
             f"    try:\n        main({argv!r})\n    except SystemExit:\n        pass")
    modules = _imported_after(probe)
    assert "numpy" not in modules and not [m for m in modules if m.startswith("m3c2kit.") and not m.startswith(
        ("m3c2kit.base", "m3c2kit.cli"))], modules
    assert not [m for m in modules if m.startswith("m3c2kit.cli.") and m not in (
        "m3c2kit.cli.main", "m3c2kit.cli.parser", "m3c2kit.cli.command_index")], modules


def test_a_command_builds_its_own_parser_only():
    modules = _imported_after("from m3c2kit.cli import main as cli\nparser = cli.make_parser('info')\n"
                              "parser.parse_args(['info', 'a.laz'])")
    assert "m3c2kit.cli.commands" in modules
    assert not {"m3c2kit.cli.series", "m3c2kit.cli.classify", "m3c2kit.cli.compare"} & set(modules)


def test_the_index_lists_every_subcommand_the_parser_builds():
    from m3c2kit.cli.command_index import COMMANDS
    from m3c2kit.cli.main import make_parser
    sub = next(a for a in make_parser()._actions if a.dest == "command")
    assert list(sub.choices) == list(COMMANDS)
    assert [c.help for c in sub._choices_actions] == [text for _, _, text in COMMANDS.values()]


def test_the_lazy_public_names_are_the_modules_own():
    import m3c2kit
    from m3c2kit import api, engine, io, output, run
    assert m3c2kit.compare is api.compare and m3c2kit.read is io.read_cloud and m3c2kit.info is io.info
    assert m3c2kit.write is output.writing.write and m3c2kit.normals is run.in_memory.normals
    assert m3c2kit.Result is engine.result.Result and set(m3c2kit.__all__) <= set(dir(m3c2kit))
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        m3c2kit.nope  # noqa: B018


def test_building_the_parser_imports_no_heavy_library():
    modules = _imported_after("from m3c2kit.cli import main as cli\nparser = cli.make_parser()\n"
                              "parser.parse_args(['compare', 'a.laz', 'b.laz', '-o', 'c.laz'])")
    assert _heavy(modules, HEAVY + OWN) == []


@pytest.mark.parametrize("suffix", [".laz"])
def test_reading_a_las_file_imports_laspy(tmp_path, suffix):
    # The other side of the lazy import: reading LAS still works, through laspy.
    path = tmp_path / f"p{suffix}"
    code = (f"import numpy as np, m3c2kit\nm3c2kit.io.write_cloud_table({str(path)!r}, np.eye(3), {{}})\n"
            f"c = m3c2kit.read({str(path)!r})\nassert c.xyz.shape == (3, 3)")
    assert "laspy" in _imported_after(code)
