"""m3c2kit:series_objects, `m3c2 series objects`: 4D objects-by-change (Anders et al. 2021) of a
series store."""
from qgis.core import QgsProcessingParameterFile, QgsProcessingParameterFileDestination

from ..compat import FOLDER
from ..options import Opt
from .simple import OptionsAlgorithm


class SeriesObjectsAlgorithm(OptionsAlgorithm):
    NAME = "series_objects"
    DISPLAY = "4D objects-by-change of a series"
    HELP = ("m3c2 series objects: 4D objects-by-change (Anders et al. 2021) of a series store (m3c2 series, a Zarr "
            "folder): seeds from change points, region growing on the normalised DTW with adaptive thresholds, "
            "filters. Writes OUTPUT (CSV), OUTPUT's _members.csv beside it, and the store's `object` label per core "
            "point and epoch (the store is changed). Empty parameters take m3c2's defaults (py4dgeo's).")
    OPTIONS = (Opt("WINDOW_WIDTH", "--window-width", "integer", "Sliding window of the change-point detection", minimum=1),
               Opt("WINDOW_MIN_SIZE", "--window-min-size", "integer", "Fewest epochs between two change points",
                   minimum=1),
               Opt("WINDOW_JUMP", "--window-jump", "integer", "Epochs between change-point candidates", minimum=1),
               Opt("WINDOW_PENALTY", "--window-penalty", "real", "Least cost decrease of a change point"),
               Opt("MIN_PERIOD", "--min-period", "integer", "Fewest epochs of a seed's change", minimum=1),
               Opt("HEIGHT_THRESHOLD", "--height-threshold", "real", "Least magnitude of a seed's change"),
               Opt("FINISHED_ONLY", "--finished-only", "flag", "Drop seeds still growing at the last epoch"),
               Opt("SEED_SUBSAMPLING", "--seed-subsampling", "integer", "Search every k-th core point for seeds",
                   minimum=1),
               Opt("NEIGHBOURHOOD_RADIUS", "--neighbourhood-radius", "real", "Core points this close are adjacent"),
               Opt("THRESHOLDS", "--thresholds", "text", "DTW thresholds to choose from, in (0, 1], comma separated"),
               Opt("MIN_SEGMENTS", "--min-segments", "integer", "Fewest core points of an object", minimum=1),
               Opt("MAX_SEGMENTS", "--max-segments", "integer", "Most core points of an object (0: no limit)",
                   minimum=0),
               Opt("MAX_CV", "--max-cv", "real", "Largest coefficient of variation of an object's DTW"),
               Opt("DTW", "--dtw", "choice", "Seeds and DTW alignment: baseline (median before the change), "
                   "seed-start, or py4dgeo (py4dgeo 1.2.0's rule)", ("baseline", "seed-start", "py4dgeo")),
               Opt("USE", "--use", "choice", "The series: smoothed_distance when present (auto), or distance (raw)",
                   ("auto", "smoothed", "raw")))

    def initAlgorithm(self, config=None):  # noqa: N802 - QGIS's name
        self.addParameter(QgsProcessingParameterFile("STORE", "Series store (a Zarr folder)", behavior=FOLDER))
        self.add_options()
        self.addParameter(QgsProcessingParameterFileDestination("OUTPUT", "Objects table", "CSV (*.csv)"))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802 - QGIS's name
        output = self.output_path(parameters, "OUTPUT", context)
        args = ["series", "objects", self.file_path(parameters, "STORE", context), "-o", output]
        self.m3c2(args + self.option_arguments(parameters, context), feedback)
        return {"OUTPUT": output}
