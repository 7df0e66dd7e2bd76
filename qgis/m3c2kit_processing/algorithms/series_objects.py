"""m3c2kit:series_objects, `m3c2 series objects`: 4D objects-by-change (Anders et al. 2021) of a
series store."""
from qgis.core import QgsProcessingParameterFile, QgsProcessingParameterFileDestination

from ..compat import FOLDER
from ..options import form_options
from .simple import OptionsAlgorithm


class SeriesObjectsAlgorithm(OptionsAlgorithm):
    NAME = "series_objects"
    DISPLAY = "4D objects-by-change of a series"
    HELP = ("m3c2 series objects: 4D objects-by-change (Anders et al. 2021) of a series store (m3c2 series, a Zarr "
            "folder): seeds from change points, region growing on the normalised DTW with adaptive thresholds, "
            "filters. Writes OUTPUT (CSV), OUTPUT's _members.csv beside it, and the store's `object` label per core "
            "point and epoch (the store is changed). Empty parameters take m3c2's defaults (py4dgeo's).")
    # Every option of `m3c2 series objects`, from the command line's own parser (series_forms.json,
    # made by python -m m3c2kit.cli.forms_export): a hand-written copy drifted (--use lacked kalman,
    # three minimums were not m3c2's).
    OPTIONS = form_options("objects")

    def initAlgorithm(self, config=None):  # noqa: N802 - QGIS's name
        self.addParameter(QgsProcessingParameterFile("STORE", "Series store (a Zarr folder)", behavior=FOLDER))
        self.add_options()
        self.addParameter(QgsProcessingParameterFileDestination("OUTPUT", "Objects table", "CSV (*.csv)"))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802 - QGIS's name
        output = self.output_path(parameters, "OUTPUT", context)
        args = ["series", "objects", self.file_path(parameters, "STORE", context), "-o", output]
        self.m3c2(args + self.option_arguments(parameters, context), feedback)
        return {"OUTPUT": output}
