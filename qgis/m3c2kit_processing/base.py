"""What every m3c2kit algorithm shares: its group, its help, inputs as files or point-cloud
layers, and the run of m3c2."""
import os

from qgis.core import (QgsPointCloudLayer, QgsProcessingAlgorithm, QgsProcessingException,
                       QgsProcessingParameterFile, QgsProcessingUtils)

from . import runner
from .compat import FILE

CLOUD_FILTER = "Point clouds (*.laz *.las *.ply *.e57 *.csv *.txt *.xyz *.asc *.npy);;All files (*)"
DOCS = "https://github.com/m3c2kit/m3c2kit/blob/main/docs/qgis.md"
#: The help the plugin's zip carries (scripts/build-qgis-plugin.sh copies docs/qgis.md there).
BUNDLED_HELP = os.path.join(os.path.dirname(os.path.abspath(__file__)), "help", "qgis.md")


def help_url() -> str:
    """The installed plugin's own copy of its help, else (a plugin run from the repository) docs/qgis.md online."""
    if os.path.isfile(BUNDLED_HELP):
        from qgis.PyQt.QtCore import QUrl
        return QUrl.fromLocalFile(BUNDLED_HELP).toString()
    return DOCS


def cloud_parameter(name, description, optional=False):
    """A point-cloud input: a file, or a point-cloud layer of the project (its file is used)."""
    param = QgsProcessingParameterFile(name, description, behavior=FILE, optional=optional, fileFilter=CLOUD_FILTER)
    param.setHelp("a point-cloud file, or the name or id of a point-cloud layer of the project (its file)")
    return param


class M3C2Algorithm(QgsProcessingAlgorithm):
    """A QGIS algorithm that runs one `m3c2` command. Subclasses give NAME, DISPLAY, HELP."""

    NAME = ""
    DISPLAY = ""
    HELP = ""
    GROUP = "M3C2"

    def name(self):
        return self.NAME

    def displayName(self):  # noqa: N802 - QGIS's name
        return self.DISPLAY

    def group(self):
        return self.GROUP

    def groupId(self):  # noqa: N802 - QGIS's name
        return self.GROUP.lower().replace(" ", "_")

    def createInstance(self):  # noqa: N802 - QGIS's name
        return type(self)()

    def helpUrl(self):  # noqa: N802 - QGIS's name
        return help_url()

    def shortHelpString(self):  # noqa: N802 - QGIS's name
        lines = [self.HELP, ""]
        for param in self.parameterDefinitions():
            if param.help():
                lines.append(f"<b>{param.description()}</b> [{param.name()}]: {param.help()}")
        return "<br>".join(lines)

    def cloud_path(self, parameters, name, context):
        """The file of input `name` (a path, or a point-cloud layer's source); None when not given."""
        value = self.parameterAsString(parameters, name, context)
        if not value:
            return None
        if os.path.exists(value):
            return runner.path_argument(value)
        layer = QgsProcessingUtils.mapLayerFromString(value, context)
        if layer is None:
            return runner.path_argument(value)  # m3c2 names the missing file in its own message
        if not isinstance(layer, QgsPointCloudLayer):
            raise QgsProcessingException(f"{name}: {layer.name()} is not a point-cloud layer: m3c2 compares point "
                                         "clouds (a file, or a point-cloud layer's file)")
        return runner.path_argument(layer.source())

    def output_path(self, parameters, name, context):
        """The file output `name`, as m3c2 reads a path (runner.path_argument)."""
        return runner.path_argument(self.parameterAsFileOutput(parameters, name, context))

    def file_path(self, parameters, name, context):
        """The file (or folder) input `name`, as m3c2 reads a path; None when not given."""
        value = self.parameterAsFile(parameters, name, context)
        return runner.path_argument(value) if value else None

    def m3c2(self, arguments, feedback, progress=False):
        return runner.run(arguments, feedback, progress=progress)
