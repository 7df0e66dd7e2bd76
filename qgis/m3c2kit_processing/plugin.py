"""The plugin: registers the Processing provider (in QGIS and in qgis_process, which calls
initProcessing for plugins whose metadata says hasProcessingProvider=yes)."""
from qgis.core import QgsApplication

from .provider import M3C2kitProvider


class M3C2kitPlugin:
    def __init__(self, iface=None):
        self.iface = iface
        self.provider = None

    def initProcessing(self):  # noqa: N802 - QGIS's name
        if self.provider is None:
            self.provider = M3C2kitProvider()
            QgsApplication.processingRegistry().addProvider(self.provider)

    def initGui(self):  # noqa: N802 - QGIS's name
        self.initProcessing()

    def unload(self):
        if self.provider is not None:
            QgsApplication.processingRegistry().removeProvider(self.provider)
            self.provider = None
