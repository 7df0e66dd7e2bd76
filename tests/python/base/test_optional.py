"""Optional features behind extras (python/m3c2kit/base/optional.py, issue 13 point 9): with the
library of an extra missing (simulated by a None entry in sys.modules, which makes its import
fail as an uninstalled one does), importing m3c2kit and running the core still work, and the
feature fails with a message naming its extra and the pip command that installs it."""
from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest

from child_env import child_env
from m3c2kit.base import optional
from m3c2kit.base.errors import M3C2Error

EXTRAS = {"rasterio": "raster", "pye57": "e57", "distributed": "dask", "dask": "dask", "matplotlib": "report"}


@pytest.fixture
def absent(monkeypatch):
    """absent("pye57") makes `import pye57` (and its submodules) fail as if not installed."""
    def block(name: str) -> None:
        for mod in [m for m in sys.modules if m == name or m.startswith(name + ".")]:
            monkeypatch.delitem(sys.modules, mod)
        monkeypatch.setitem(sys.modules, name, None)
    return block


def test_require_names_the_extra_and_the_pip_command(absent):
    absent("pye57")
    with pytest.raises(optional.MissingExtraError) as info:
        optional.require("pye57", extra="e57", purpose="reading .e57 files")
    assert str(info.value).startswith("reading .e57 files needs the e57 extra: pip install 'm3c2kit[e57]'")
    # An M3C2Error (the CLI prints it and exits 1, no traceback) and an ImportError (code that
    # probes for the library with `except ImportError` still works).
    assert isinstance(info.value, M3C2Error) and isinstance(info.value, ImportError)
    assert info.value.extra == "e57" and info.value.name == "pye57"


def test_require_of_a_submodule_blames_the_library(absent):
    absent("rasterio")
    with pytest.raises(optional.MissingExtraError, match=r"needs the raster extra: pip install 'm3c2kit\[raster\]'"):
        optional.require("rasterio.transform", extra="raster", purpose="GeoTIFF rasters")


def test_a_broken_dependency_of_an_installed_library_is_not_called_a_missing_extra(monkeypatch, tmp_path):
    # The library imports, but one of its own imports fails: that error is the one to see.
    (tmp_path / "fakelib.py").write_text("import a_dependency_that_is_missing\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(ModuleNotFoundError, match="a_dependency_that_is_missing") as info:
        optional.require("fakelib", extra="x", purpose="p")
    assert not isinstance(info.value, optional.MissingExtraError)


def test_an_installed_library_that_fails_to_import_is_named_with_its_real_cause(monkeypatch, tmp_path):
    """Issue 44: Debian's matplotlib (built for numpy 1.x) beside numpy 2.x failed with "no module
    named 'matplotlib'" and the advice to install the extra that was installed."""
    (tmp_path / "brokenlib.py").write_text("raise ImportError('numpy.core.multiarray failed to import')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(M3C2Error) as info:
        optional.require("brokenlib", extra="report", purpose="drawing --report")
    text = str(info.value)
    assert not isinstance(info.value, optional.MissingExtraError) and "no module named" not in text
    assert "brokenlib, which is installed but does not import: numpy.core.multiarray failed to import" in text


def test_lazy_module_imports_only_when_used(absent):
    absent("pye57")
    stand_in = optional.lazy_module("pye57", extra="e57", purpose="reading .e57 files")  # no error yet
    with pytest.raises(optional.MissingExtraError, match="e57 extra"):
        stand_in.E57


def test_reading_e57_without_pye57(absent, tmp_path):
    from m3c2kit.io import e57
    path = tmp_path / "scan.e57"
    path.write_bytes(b"ASTM-E57" + bytes(1024))
    absent("pye57")
    with pytest.raises(optional.MissingExtraError, match=r"reading \.e57 files needs the e57 extra: pip install 'm3c2kit\[e57\]'"):
        e57.read(path)


def test_rasters_without_rasterio(absent):
    from m3c2kit.run import raster
    absent("rasterio")
    with pytest.raises(optional.MissingExtraError, match="raster extra"):
        raster.rasterio_crs("EPSG:32617")
    with pytest.raises(optional.MissingExtraError, match="raster extra"):
        raster.write_rasters({}, {}, None, None)


def test_report_figures_without_matplotlib(absent):
    absent("matplotlib")
    sys.modules.pop("m3c2kit.output.report.figures", None)
    try:
        with pytest.raises(optional.MissingExtraError, match=r"needs the report extra: pip install 'm3c2kit\[report\]'"):
            import m3c2kit.output.report.figures  # noqa: F401
    finally:
        sys.modules.pop("m3c2kit.output.report.figures", None)  # re-imported with matplotlib by later tests


def test_analysis_plots_without_matplotlib(absent):
    from m3c2kit.analysis import common
    absent("matplotlib")
    with pytest.raises(optional.MissingExtraError, match="report extra"):
        common.pyplot()


def test_dask_without_distributed(absent):
    from m3c2kit.run import dask
    absent("distributed")
    with pytest.raises(optional.MissingExtraError, match=r"needs the dask extra: pip install 'm3c2kit\[dask\]'"):
        dask.connect("tcp://127.0.0.1:1")


def _blocking_prelude(modules) -> str:
    return "import sys\n" + "".join(f"sys.modules[{m!r}] = None\n" for m in modules)


@pytest.mark.slow
def test_the_core_install_imports_and_computes_without_any_extra(tmp_path):
    """A child interpreter where none of the extras' libraries can be imported: `import m3c2kit`,
    the command line's module and a comparison to LAZ all work."""
    script = _blocking_prelude(EXTRAS) + textwrap.dedent(f"""
        import numpy as np
        import m3c2kit, m3c2kit.cli.main
        x, y = np.meshgrid(np.linspace(0, 4, 41), np.linspace(0, 4, 41))
        ref = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
        cmp = ref + [0, 0, 0.25]
        np.save({str(tmp_path / 'ref.npy')!r}, ref)
        np.save({str(tmp_path / 'cmp.npy')!r}, cmp)
        code = m3c2kit.cli.main.main([
            "compare", {str(tmp_path / 'ref.npy')!r}, {str(tmp_path / 'cmp.npy')!r},
            "-o", {str(tmp_path / 'out.laz')!r}, "--core-spacing", "1", "--normal-scale", "1",
            "--projection-scale", "1", "--max-depth", "1", "--quiet"])
        assert code == 0, code
        assert not any(sys.modules.get(m) for m in {list(EXTRAS)!r}), "an extra was imported"
    """)
    proc = subprocess.run([sys.executable, "-c", script], env=child_env(), capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    import laspy
    las = laspy.read(tmp_path / "out.laz")
    assert np.allclose(np.asarray(las["distance"]), 0.25, atol=1e-9)


@pytest.mark.slow
@pytest.mark.parametrize("args, extra", [
    (["--grid", "1"], "raster"),
    (["--report", "{tmp}/report.html"], "report"),
])
def test_the_command_line_names_the_missing_extra(tmp_path, args, extra):
    modules = {"raster": ["rasterio"], "report": ["matplotlib"]}[extra]
    np.save(tmp_path / "ref.npy", np.column_stack([np.repeat(np.arange(9.0), 9), np.tile(np.arange(9.0), 9), np.zeros(81)]))
    np.save(tmp_path / "cmp.npy", np.load(tmp_path / "ref.npy") + [0, 0, 0.5])
    argv = ["compare", str(tmp_path / "ref.npy"), str(tmp_path / "cmp.npy"), "-o", str(tmp_path / "out.csv"),
            "--max-depth", "1"] + [a.format(tmp=tmp_path) for a in args]
    if extra != "raster":  # --grid imposes vertical normals and its own core points
        argv += ["--core-spacing", "2", "--normal-scale", "2", "--projection-scale", "2"]
    script = _blocking_prelude(modules) + f"from m3c2kit.cli.main import main\nsys.exit(main({argv!r}))\n"
    proc = subprocess.run([sys.executable, "-c", script], env=child_env(), capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1, (proc.returncode, proc.stderr)
    assert f"needs the {extra} extra: pip install 'm3c2kit[{extra}]'" in proc.stderr
    assert "Traceback" not in proc.stderr
