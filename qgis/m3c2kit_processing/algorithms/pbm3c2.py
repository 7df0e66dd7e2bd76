"""m3c2kit:pbm3c2, `m3c2 pbm3c2`: plane-based M3C2 between paired planar segments (Zahs et al. 2022)."""
from qgis.core import (QgsProcessingOutputVectorLayer, QgsProcessingParameterFile,
                       QgsProcessingParameterFileDestination, QgsProcessingParameterNumber)

from .. import results, table
from ..base import M3C2Algorithm, cloud_parameter
from ..compat import DOUBLE, FILE
from ..options import threads, threads_arguments
from .compare import OUTPUT_FILTER

# Rows this algorithm offers as its own file parameters (an input file, an output).
FILES = ("training", "per_point")


class PBM3C2Algorithm(M3C2Algorithm):
    NAME = "pbm3c2"
    DISPLAY = "PB-M3C2: change between paired planes"
    HELP = ("m3c2 pbm3c2: both clouds cut into planar segments (region growing on normals, or SEGMENTS: a field of "
            "segment ids), each reference segment paired with the compared segment of the same surface (by default the "
            "one its points' nearest compared points mostly lie in; or the nearest within a search radius and angle; "
            "or a random forest trained on labelled pairs), and the change: the "
            "distance between the two planes with its LOD (eq. 1), far below M3C2's on planar patches. One point per "
            "reference segment, at its centroid; unpaired segments have no distance and a status "
            "(docs/pbm3c2.md). Empty parameters take m3c2's defaults.")
    COMMAND = "pbm3c2"

    def initAlgorithm(self, config=None):  # noqa: N802 - QGIS's name
        self.addParameter(cloud_parameter("REFERENCE", "Reference cloud"))
        self.addParameter(cloud_parameter("COMPARED", "Compared cloud"))
        scale = QgsProcessingParameterNumber("NORMAL_SCALE", "Normal scale D of the segmentation (diameter)",
                                             type=DOUBLE, defaultValue=None, optional=True, minValue=0.0)
        scale.setHelp("each point's normal from its neighbours within this diameter; empty: m3c2 suggest's D, "
                      "from the data; not with SEGMENTS. m3c2 option: --normal-scale.")
        self.addParameter(scale)
        for row in table.rows(self.COMMAND):
            if row["name"] not in FILES:
                self.addParameter(table.definition(row))
        self.addParameter(QgsProcessingParameterFile("TRAINING", "Training pairs (CSV: reference id, compared id, "
                                                     "1 or 0), with Correspondence forest", behavior=FILE,
                                                     optional=True, fileFilter="CSV (*.csv)"))
        for name in ("registration_error", "confidence"):
            self.addParameter(table.definition(next(r for r in table.rows() if r["name"] == name)))
        self.addParameter(threads()[0])
        self.addParameter(QgsProcessingParameterFileDestination("OUTPUT", "Segment pairs", OUTPUT_FILTER))
        self.addParameter(QgsProcessingParameterFileDestination("PER_POINT", "Reference points with their "
                                                                "segment's change", OUTPUT_FILTER, optional=True,
                                                                createByDefault=False))
        self.addOutput(QgsProcessingOutputVectorLayer("OUTPUT_LAYER", "Segment pairs layer"))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802 - QGIS's name
        output = self.output_path(parameters, "OUTPUT", context)
        args = ["pbm3c2", self.cloud_path(parameters, "REFERENCE", context),
                self.cloud_path(parameters, "COMPARED", context), "-o", output]
        for row in table.rows(self.COMMAND) + [r for r in table.rows() if r["name"] in ("registration_error",
                                                                                     "confidence")]:
            if row["name"] not in FILES:
                args += table.arguments(self, row, parameters, context)
        if parameters.get("NORMAL_SCALE") is not None:
            args += ["--normal-scale", repr(self.parameterAsDouble(parameters, "NORMAL_SCALE", context))]
        training = self.file_path(parameters, "TRAINING", context)
        if training:
            args += ["--training", training]
        per_point = self.parameterAsFileOutput(parameters, "PER_POINT", context)
        if per_point:
            args += ["--per-point", self.output_path(parameters, "PER_POINT", context)]
        self.m3c2(args + threads_arguments(self, parameters, context), feedback)
        return {"OUTPUT": output, "OUTPUT_LAYER": results.table_layer(output, feedback, context)}
