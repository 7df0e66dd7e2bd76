"""m3c2kit:classify_apply, `m3c2 classify apply`: a CANUPO classifier applied to a cloud."""
from qgis.core import QgsProcessingParameterFile, QgsProcessingParameterFileDestination

from ..base import cloud_parameter
from ..compat import FILE
from ..options import Opt
from .compare import OUTPUT_FILTER
from .simple import OptionsAlgorithm


class ClassifyApplyAlgorithm(OptionsAlgorithm):
    NAME = "classify_apply"
    DISPLAY = "Classify a cloud (CANUPO)"
    HELP = ("m3c2 classify apply: writes the cloud with the class a CANUPO classifier (m3c2 classify train, or "
            "qCANUPO's .prm; Brodu & Lague 2012) predicts, in the classification field (or LABEL_FIELD), and a "
            "'confidence' field (0 to 1). The output is the whole cloud: it is not loaded as a vector layer (open "
            "it as a point cloud where QGIS reads LAZ).")
    OPTIONS = (Opt("LABEL_FIELD", "--label-field", "text", "Field receiving the class code"),
               Opt("CLASS_MAP", "--class-map", "text", "LABEL=CODE,... codes written for the classifier's labels"),
               Opt("UNCLASSIFIED", "--unclassified", "integer", "Code of points without features"),
               Opt("DROP_NONFINITE", "--drop-nonfinite", "flag", "Drop points with NaN/Inf coordinates"))

    def initAlgorithm(self, config=None):  # noqa: N802 - QGIS's name
        self.addParameter(cloud_parameter("INPUT", "Point cloud to classify"))
        self.addParameter(QgsProcessingParameterFile("CLASSIFIER", "Classifier (--classifier)", behavior=FILE))
        self.add_options()
        self.addParameter(QgsProcessingParameterFileDestination("OUTPUT", "Classified cloud", OUTPUT_FILTER))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802 - QGIS's name
        output = self.output_path(parameters, "OUTPUT", context)
        args = ["classify", "apply", self.cloud_path(parameters, "INPUT", context), "--classifier",
                self.file_path(parameters, "CLASSIFIER", context), "-o", output]
        self.m3c2(args + self.option_arguments(parameters, context), feedback)
        return {"OUTPUT": output}
