"""m3c2kit:series_objects, `m3c2 series objects`: 4D objects-by-change (Anders et al. 2021) of a
series store."""
from qgis.core import QgsProcessingParameterFile, QgsProcessingParameterFileDestination

from .. import table
from ..compat import FOLDER
from ..options import threads, threads_arguments
from ..base import M3C2Algorithm


class SeriesObjectsAlgorithm(M3C2Algorithm):
    NAME = "series_objects"
    DISPLAY = "4D objects-by-change of a series"
    HELP = ("m3c2 series objects: 4D objects-by-change (Anders et al. 2021) of a series store (m3c2 series, a Zarr "
            "folder): seeds from change points, region growing on the normalised DTW with adaptive thresholds, "
            "filters. Writes OUTPUT (CSV), OUTPUT's _members.csv beside it, and the store's `object` label per core "
            "point and epoch (the store is changed). Empty parameters take m3c2's defaults (py4dgeo's).")
    # Every option of `m3c2 series objects`: the parameter table's rows of that command
    # (parameters.json, python -m m3c2kit.settings.export), as compare's; a hand-written copy
    # drifted (--use lacked kalman, three minimums were not m3c2's).
    COMMAND = "series objects"

    def initAlgorithm(self, config=None):  # noqa: N802 - QGIS's name
        self.addParameter(QgsProcessingParameterFile("STORE", "Series store (a Zarr folder)", behavior=FOLDER))
        for row in table.rows(self.COMMAND):
            self.addParameter(table.definition(row))
        self.addParameter(threads()[0])
        self.addParameter(QgsProcessingParameterFileDestination("OUTPUT", "Objects table", "CSV (*.csv)"))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802 - QGIS's name
        output = self.output_path(parameters, "OUTPUT", context)
        args = ["series", "objects", self.file_path(parameters, "STORE", context), "-o", output]
        for row in table.rows(self.COMMAND):
            args += table.arguments(self, row, parameters, context)
        self.m3c2(args + threads_arguments(self, parameters, context), feedback)
        return {"OUTPUT": output}
