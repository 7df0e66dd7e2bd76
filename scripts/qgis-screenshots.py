"""The screenshots of docs/qgis.md, taken from QGIS itself (Debian's QGIS under Xvfb):
docs/qgis/compare-dialog.png (the M3C2 compare dialog, filled in for the README's Toronto demo)
and docs/qgis/styled-result.png (QGIS's window with the result loaded as the algorithm loads it).

    PATH=/usr/bin:/bin:$PWD/.venv/bin QGIS_PLUGINPATH=$PWD/qgis \\
      xvfb-run -a -s "-screen 0 1280x860x24" qgis --nologo --noversioncheck --code scripts/qgis-screenshots.py

(/usr/bin before the virtual environment: QGIS's Python finds its home through the first python3.)"""
import os
import sys
import tempfile

from qgis.core import QgsApplication, QgsProject
from qgis.PyQt.QtCore import Qt, QTimer
from qgis.PyQt.QtGui import QImage
from qgis.PyQt.QtWidgets import QApplication, QDockWidget
from qgis.utils import iface

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__))) if "__file__" in globals() else os.getcwd()
OUT = os.path.join(ROOT, "docs", "qgis")
TORONTO = os.path.join(ROOT, "data", "toronto-ttp")
WORK = tempfile.mkdtemp(prefix="m3c2kit-screenshots-")
PARAMETERS = {"REFERENCE": os.path.join(TORONTO, "TTP_15.laz"), "COMPARED": os.path.join(TORONTO, "TTP_23.laz"),
              "CORE_SPACING": 5, "NORMAL_SCALE": "8:40:8", "PROJECTION_SCALE": 10, "MAX_DEPTH": 30,
              "OUTPUT": os.path.join(WORK, "toronto-m3c2.laz")}
_KEEP = []


def settle(seconds=1.0):
    loop_until = QTimer()
    loop_until.setSingleShot(True)
    loop_until.start(int(seconds * 1000))
    while loop_until.isActive():
        QApplication.processEvents()


def provider():
    registry = QgsApplication.processingRegistry()
    if registry.providerById("m3c2kit") is None:  # the plugin not enabled in this profile
        sys.path.insert(0, os.path.join(ROOT, "qgis"))
        from m3c2kit_processing.provider import M3C2kitProvider
        _KEEP.append(M3C2kitProvider())
        registry.addProvider(_KEEP[-1])


def save(widget, name):
    """A PNG of `widget`, its colours reduced to the 256 it uses most (median cut; the docs' images
    stay under 200 KB; Debian's python3-pil, a QGIS dependency)."""
    from PIL import Image
    path = os.path.join(OUT, name)
    widget.grab().toImage().convertToFormat(QImage.Format_RGB888).save(path, "PNG")
    with Image.open(path) as image:
        reduced = image.convert("RGB").quantize(256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    reduced.save(path, optimize=True)
    print(f"wrote {path} ({os.path.getsize(path)} bytes)")


def main():
    try:
        import processing
        provider()
        iface.mainWindow().resize(1100, 760)
        dialog = processing.createAlgorithmDialog("m3c2kit:compare", PARAMETERS)
        dialog.resize(980, 760)
        dialog.show()
        settle()
        save(dialog, "compare-dialog.png")
        dialog.close()
        results = processing.runAndLoadResults("m3c2kit:compare", PARAMETERS)
        settle()
        layer = QgsProject.instance().mapLayersByName(os.path.basename(PARAMETERS["OUTPUT"]))[0]
        for dock in iface.mainWindow().findChildren(QDockWidget):  # the layers panel only, its legend open
            dock.setVisible(dock.objectName() == "Layers")
            if dock.objectName() == "Layers":  # wide enough for the neutral class's whole label
                iface.mainWindow().resizeDocks([dock], [540], Qt.Orientation.Horizontal)
        QgsProject.instance().layerTreeRoot().findLayer(layer.id()).setExpanded(True)
        canvas = iface.mapCanvas()
        canvas.setExtent(layer.extent())
        canvas.refresh()
        settle(3)
        save(iface.mainWindow(), "styled-result.png")
        print(results)
    finally:
        QgsProject.instance().clear()
        QTimer.singleShot(0, QgsApplication.instance().quit)


QTimer.singleShot(2000, main)
