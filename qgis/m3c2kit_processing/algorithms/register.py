"""m3c2kit:register, `m3c2 register`: the rigid motion of the compared cloud onto the reference by
point-to-plane ICP on stable areas, its covariance and the registration error reg of eq. (1)
(docs/registration.md), for M3C2 compare's TRANSFORM, REGISTRATION_ERROR and ALIGNMENT_COVARIANCE."""
import json

from qgis.core import (QgsProcessingException, QgsProcessingOutputNumber, QgsProcessingParameterBoolean,
                       QgsProcessingParameterFile, QgsProcessingParameterFileDestination,
                       QgsProcessingParameterNumber)

from .. import table
from ..base import M3C2Algorithm, cloud_parameter
from ..compat import DOUBLE, FILE
from ..options import threads, threads_arguments

POLYGON_FILTER = "Polygons (*.geojson *.json *.wkt *.txt);;All files (*)"


class RegisterAlgorithm(M3C2Algorithm):
    NAME = "register"
    DISPLAY = "Register the compared cloud onto the reference (ICP on stable areas)"
    HELP = ("m3c2 register: point-to-plane ICP (Chen & Medioni 1992) of the compared cloud onto the reference on "
            "stable areas: STABLE polygons (plan view), every point, or found by excluding what M3C2 finds "
            "significant, round after round (AUTO_STABLE). OUTPUT is the registration (.json): the 4x4 matrix "
            "(compared onto reference), its 6x6 covariance and the registration error reg of eq. (1), which M3C2 "
            "compare takes as TRANSFORM, REGISTRATION_ERROR and ALIGNMENT_COVARIANCE (docs/registration.md). "
            "Empty parameters take m3c2's defaults.")
    COMMAND = "register"

    def initAlgorithm(self, config=None):  # noqa: N802 - QGIS's name
        self.addParameter(cloud_parameter("REFERENCE", "Reference cloud (the one that does not move)"))
        self.addParameter(cloud_parameter("COMPARED", "Compared cloud (the one moved onto the reference)"))
        stable = QgsProcessingParameterFile("STABLE", "Stable areas (GeoJSON or WKT polygons)", behavior=FILE,
                                            optional=True, fileFilter=POLYGON_FILTER)
        stable.setHelp("the points inside these polygons (plan view) are registered; empty: every point, or "
                       "AUTO_STABLE. m3c2 option: --stable.")
        self.addParameter(stable)
        auto = QgsProcessingParameterBoolean("AUTO_STABLE", "Find the stable areas (auto stable)", defaultValue=False,
                                             optional=True)
        auto.setHelp("register on every point, compare with M3C2 at the data's scales, drop the points within d of "
                     "a significant core point, register again, until the stable set settles or the most rounds; "
                     "not with STABLE. m3c2 option: --auto-stable.")
        self.addParameter(auto)
        scale = QgsProcessingParameterNumber("NORMAL_SCALE", "Normal scale D of the targets' planes (diameter)",
                                             type=DOUBLE, defaultValue=None, optional=True, minValue=0.0)
        scale.setHelp("each reference point's plane from its neighbours within this diameter; empty: m3c2 suggest's "
                      "D, from the data. m3c2 option: --normal-scale.")
        self.addParameter(scale)
        for row in table.rows(self.COMMAND):
            self.addParameter(table.definition(row))
        self.addParameter(threads()[0])
        self.addParameter(QgsProcessingParameterFileDestination("OUTPUT", "Registration", "JSON (*.json)"))
        self.addOutput(QgsProcessingOutputNumber("REGISTRATION_ERROR", "Registration error (reg of eq. 1)"))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802 - QGIS's name
        output = self.output_path(parameters, "OUTPUT", context)
        args = ["register", self.cloud_path(parameters, "REFERENCE", context),
                self.cloud_path(parameters, "COMPARED", context), "-o", output]
        stable = self.file_path(parameters, "STABLE", context)
        if stable:
            args += ["--stable", stable]
        if self.parameterAsBool(parameters, "AUTO_STABLE", context):
            args.append("--auto-stable")
        if parameters.get("NORMAL_SCALE") is not None:
            args += ["--normal-scale", repr(self.parameterAsDouble(parameters, "NORMAL_SCALE", context))]
        for row in table.rows(self.COMMAND):
            args += table.arguments(self, row, parameters, context)
        self.m3c2(args + threads_arguments(self, parameters, context), feedback)
        written = self.parameterAsFileOutput(parameters, "OUTPUT", context)
        try:
            with open(written, encoding="utf-8") as f:
                error = float(json.load(f)["registration_error"])
        except (OSError, ValueError, KeyError, TypeError) as e:
            raise QgsProcessingException(f"{written}: no registration error in m3c2 register's output ({e})") from e
        return {"OUTPUT": written, "REGISTRATION_ERROR": error}
