"""The Processing provider `m3c2kit`: its algorithms and its one setting, the m3c2 executable
(as QGIS's other external providers name their tools' paths)."""
import os

from qgis.core import QgsProcessingProvider
from qgis.PyQt.QtGui import QIcon

from . import runner

ICON = os.path.join(os.path.dirname(__file__), "icon.svg")


def _config():
    """QGIS's Processing settings (the Processing plugin's ProcessingConfig), or None where the
    Processing plugin is not loaded (a bare PyQGIS script): then only PATH and M3C2_EXECUTABLE."""
    try:
        from processing.core.ProcessingConfig import ProcessingConfig, Setting
    except ImportError:
        return None, None
    return ProcessingConfig, Setting


class M3C2kitProvider(QgsProcessingProvider):
    def id(self):
        return "m3c2kit"

    def name(self):
        return "m3c2kit"

    def longName(self):  # noqa: N802 - QGIS's name
        return "m3c2kit: M3C2 point-cloud change detection"

    def icon(self):
        return QIcon(ICON)

    def load(self):
        config, setting = _config()
        if config is not None:
            config.settingIcons[self.name()] = self.icon()
            config.addSetting(setting(self.name(), runner.SETTING, "m3c2 executable (empty: found on PATH)", "",
                                      valuetype=setting.FILE))
            config.readSettings()
        self.refreshAlgorithms()
        return True

    def unload(self):
        config, _ = _config()
        if config is not None:
            config.removeSetting(runner.SETTING)

    def loadAlgorithms(self):  # noqa: N802 - QGIS's name
        from .algorithms import ALGORITHMS
        for algorithm in ALGORITHMS:
            self.addAlgorithm(algorithm())
