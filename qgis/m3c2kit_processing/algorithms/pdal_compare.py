"""m3c2kit:pdal_compare: QGIS 4's "PDAL Compare" (PDAL's filters.m3c2) by its names and meanings,
run by m3c2 compare: a PDAL user moves by renaming the algorithm. PDAL's radii become m3c2's
diameters; cyl_halflen is a half-length in both (m3c2's --max-depth)."""
from qgis.core import (QgsProcessingException, QgsProcessingOutputVectorLayer, QgsProcessingParameterEnum,
                       QgsProcessingParameterFileDestination, QgsProcessingParameterNumber)

from .. import results
from ..base import M3C2Algorithm, cloud_parameter
from ..compat import DOUBLE, INTEGER
from .compare import OUTPUT_FILTER

ORIENTATIONS = ("up", "down", "none")
ORIENT = {"up": "+z", "down": "-z"}


class PdalCompareAlgorithm(M3C2Algorithm):
    NAME = "pdal_compare"
    DISPLAY = "M3C2 compare with PDAL's parameters (PDAL Compare)"
    HELP = ("PDAL filters.m3c2's parameters (QGIS 4's PDAL Compare), computed by m3c2 compare with: --normal-scale "
            "2 x NORMAL_RADIUS, --projection-scale 2 x CYL_RADIUS (m3c2's D and d are diameters), --max-depth "
            "CYL_HALFLEN (a half-length in both), --registration-error REG_ERROR, --min-points MIN_POINTS, --orient "
            "+z (up) or -z (down), --lod z and --variance population (PDAL's statistic), --field-names pdal (PDAL's "
            "m3c2_* columns). The numbers differ from PDAL's where PDAL's are approximations: PDAL computes the "
            "variance as sum(x^2)/n - mean^2, which loses digits at large coordinates (m3c2: the same population "
            "variance without that cancellation); it stores counts as 16-bit integers (65535 at most; m3c2: exact); "
            "it multiplies by 1.96 (m3c2: the exact 95 % quantile 1.959964); it writes 0 where no distance can be "
            "computed (m3c2: NaN and a status column saying why); it runs on one thread (m3c2: every thread, the "
            "same bits for any count). ORIENTATION none (the normal's sign left as the eigen solver gives it) has "
            "no m3c2 equivalent: m3c2 always orients normals (section 3.1.2) and refuses it. Use M3C2 compare for "
            "everything PDAL lacks: multi-scale normals, median, t and bootstrap LOD, M3C2-PM and EP, rasters.")

    def initAlgorithm(self, config=None):  # noqa: N802 - QGIS's name
        self.addParameter(cloud_parameter("REFERENCE", "Reference cloud (PDAL's first input)"))
        self.addParameter(cloud_parameter("COMPARED", "Compared cloud (PDAL's second input)"))
        self.addParameter(cloud_parameter("CORE", "Core points (PDAL's third input; default: every reference point)",
                                          optional=True))
        for name, label, default in (("NORMAL_RADIUS", "Normal radius (PDAL normal_radius; D = 2 r)", 2.0),
                                     ("CYL_RADIUS", "Cylinder radius (PDAL cyl_radius; d = 2 r)", 2.0),
                                     ("CYL_HALFLEN", "Cylinder half-length (PDAL cyl_halflen; m3c2 --max-depth)", 5.0),
                                     ("REG_ERROR", "Registration error (PDAL reg_error)", 0.0)):
            param = QgsProcessingParameterNumber(name, label, type=DOUBLE, defaultValue=default, minValue=0.0)
            self.addParameter(param)
        self.addParameter(QgsProcessingParameterNumber("MIN_POINTS", "Minimum points (PDAL min_points; m3c2 "
                                                       "--min-points)", type=INTEGER, defaultValue=1, minValue=1))
        self.addParameter(QgsProcessingParameterEnum("ORIENTATION", "Orientation (PDAL orientation)",
                                                     options=list(ORIENTATIONS), defaultValue=0))
        self.addParameter(QgsProcessingParameterFileDestination("OUTPUT", "M3C2 output", OUTPUT_FILTER))
        self.addOutput(QgsProcessingOutputVectorLayer("OUTPUT_LAYER", "M3C2 result layer"))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802 - QGIS's name
        orientation = ORIENTATIONS[self.parameterAsEnum(parameters, "ORIENTATION", context)]
        if orientation not in ORIENT:
            raise QgsProcessingException("ORIENTATION none: m3c2 always orients the normals (section 3.1.2); choose "
                                         "up (PDAL's default) or down, or M3C2 compare's ORIENTATION")
        number = lambda name: self.parameterAsDouble(parameters, name, context)  # noqa: E731
        output = self.output_path(parameters, "OUTPUT", context)
        args = ["compare", self.cloud_path(parameters, "REFERENCE", context),
                self.cloud_path(parameters, "COMPARED", context), "-o", output]
        core = self.cloud_path(parameters, "CORE", context)
        if core:
            args += ["--core", core]
        args += ["--normal-scale", repr(2.0 * number("NORMAL_RADIUS")),
                 "--projection-scale", repr(2.0 * number("CYL_RADIUS")), "--max-depth", repr(number("CYL_HALFLEN")),
                 "--registration-error", repr(number("REG_ERROR")),
                 "--min-points", str(self.parameterAsInt(parameters, "MIN_POINTS", context)),
                 "--orient", ORIENT[orientation], "--lod", "z", "--variance", "population", "--field-names", "pdal"]
        self.m3c2(args + ["--progress", "json"], feedback, progress=True)
        return {"OUTPUT": output, "OUTPUT_LAYER": results.table_layer(output, feedback, context)}
