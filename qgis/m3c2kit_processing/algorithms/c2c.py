"""m3c2kit:c2c, `m3c2 c2c`: the closest-point baselines C2C and C2C_HF (section 3.4)."""
from qgis.core import QgsProcessingOutputVectorLayer, QgsProcessingParameterFileDestination

from .. import results
from ..base import cloud_parameter
from ..options import Opt
from .compare import OUTPUT_FILTER
from .simple import OptionsAlgorithm


class C2CAlgorithm(OptionsAlgorithm):
    NAME = "c2c"
    DISPLAY = "C2C and C2C_HF distances"
    HELP = ("m3c2 c2c: distance from each compared point (or core point) to the closest reference point (C2C) and, "
            "with MODEL plane, to the least-squares plane of that point's reference neighbours (C2C_HF). Unsigned, "
            "as in CloudCompare; the paper's baseline (section 3.4). The output is loaded as a point layer.")
    OPTIONS = (Opt("CORE_SPACING", "--core-spacing", "real", "Core points: the compared cloud subsampled to this "
                                                             "spacing", minimum=0.0),
               Opt("MODEL", "--model", "choice", "Local model: none (C2C) or plane (also C2C_HF)", ("none", "plane")),
               Opt("MODEL_RADIUS", "--model-radius", "real", "Model neighbours within this radius", minimum=0.0),
               Opt("MODEL_KNN", "--model-knn", "integer", "Else its k nearest reference points", minimum=1),
               Opt("RULE", "--rule", "choice", "With MODEL plane: closer (CloudCompare >= 2.5) or model (2.3)",
                   ("closer", "model")),
               Opt("DROP_NONFINITE", "--drop-nonfinite", "flag", "Drop points with NaN/Inf coordinates"))

    def initAlgorithm(self, config=None):  # noqa: N802 - QGIS's name
        self.addParameter(cloud_parameter("REFERENCE", "Reference cloud"))
        self.addParameter(cloud_parameter("COMPARED", "Compared cloud (its points are the query points)"))
        self.addParameter(cloud_parameter("CORE", "Core points (default: every compared point)", optional=True))
        self.add_options()
        self.addParameter(QgsProcessingParameterFileDestination("OUTPUT", "C2C output", OUTPUT_FILTER))
        self.addOutput(QgsProcessingOutputVectorLayer("OUTPUT_LAYER", "C2C layer"))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802 - QGIS's name
        output = self.output_path(parameters, "OUTPUT", context)
        args = ["c2c", self.cloud_path(parameters, "REFERENCE", context),
                self.cloud_path(parameters, "COMPARED", context), "-o", output]
        core = self.cloud_path(parameters, "CORE", context)
        if core:
            args += ["--core", core]
        self.m3c2(args + self.option_arguments(parameters, context), feedback)
        return {"OUTPUT": output, "OUTPUT_LAYER": results.table_layer(output, feedback, context)}
