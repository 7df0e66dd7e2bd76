"""scripts/build-qgis-plugin.sh: the zip QGIS's plugin manager installs (the plugin folder at its
root, every file of it, no caches)."""
import os
import subprocess
import sys
import zipfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import ROOT, run_tests  # noqa: E402

PLUGIN = os.path.join(ROOT, "qgis", "m3c2kit_processing")


def test_the_zip_holds_the_plugin_folder():
    done = subprocess.run(["bash", os.path.join(ROOT, "scripts", "build-qgis-plugin.sh")], capture_output=True,
                          text=True)
    assert done.returncode == 0, done.stderr
    with zipfile.ZipFile(os.path.join(ROOT, "dist", "m3c2kit_processing.zip")) as z:
        names = set(z.namelist())
        expected = set()
        for folder, dirs, files in os.walk(PLUGIN):
            dirs[:] = [x for x in dirs if x != "__pycache__"]
            for name in files:
                if not name.endswith(".pyc"):
                    expected.add(os.path.relpath(os.path.join(folder, name), os.path.dirname(PLUGIN)))
        expected.add("m3c2kit_processing/help/qgis.md")  # the help it refers to (issue 44)
        assert names == expected, names ^ expected
        with open(os.path.join(ROOT, "docs", "qgis.md"), "rb") as f:
            assert z.read("m3c2kit_processing/help/qgis.md") == f.read()
        assert all(n.startswith("m3c2kit_processing/") for n in names)
        assert not any("__pycache__" in n or n.endswith(".pyc") for n in names)
        for name in ("metadata.txt", "__init__.py", "parameters.json"):
            with open(os.path.join(PLUGIN, name), "rb") as f:
                assert z.read(f"m3c2kit_processing/{name}") == f.read()
        assert "hasProcessingProvider=yes" in z.read("m3c2kit_processing/metadata.txt").decode()


if __name__ == "__main__":
    sys.exit(run_tests(globals()))
