"""m3c2kit:pdal_compare: QGIS 4's "PDAL Compare" (pdal:compare, PDAL's filters.m3c2) by its parameter
ids, defaults and meanings, run by m3c2 compare: a model written for pdal:compare runs by changing
the algorithm id only. PDAL's radii become m3c2's diameters; the cylinder's half-length is one in
both (m3c2's --max-depth)."""
from qgis.core import (QgsProcessingException, QgsProcessingOutputVectorLayer, QgsProcessingParameterEnum,
                       QgsProcessingParameterFileDestination, QgsProcessingParameterNumber)

from .. import results
from ..base import M3C2Algorithm, cloud_parameter
from ..compat import DOUBLE, INTEGER
from .compare import OUTPUT_FILTER

#: QGIS 4's pdal:compare CYLINDER_ORIENTATION choices, in its order, and m3c2's --orient for each.
ORIENTATIONS = ("Up", "Origin", "None")
ORIENT = {"Up": "+z", "Origin": "origin"}
#: QGIS 4's pdal:compare numbers: (id, label, default), its ids and defaults (issue 44: a model
#: written for pdal:compare runs by changing the algorithm id only).
NUMBERS = (("NORMAL_RADIUS", "Normal radius (PDAL normal_radius; D = 2 r)", 2.0),
           ("CYLINDER_RADIUS", "Cylinder radius (PDAL cyl_radius; d = 2 r)", 2.0),
           ("CYLINDER_HALF_LENGTH", "Cylinder half-length (PDAL cyl_halflen; m3c2 --max-depth)", 5.0),
           ("REGISTRATION_ERROR", "Registration error (PDAL reg_error)", 0.0),
           ("SUBSAMPLING_CELL_SIZE", "Core points: the reference subsampled to this cell (0: every point)", 0.0))


class PdalCompareAlgorithm(M3C2Algorithm):
    NAME = "pdal_compare"
    DISPLAY = "M3C2 compare with PDAL's parameters (PDAL Compare)"
    HELP = ("QGIS 4's PDAL Compare (pdal:compare, PDAL's filters.m3c2) with its parameter ids and defaults, computed "
            "by m3c2 compare with: --normal-scale 2 x NORMAL_RADIUS, --projection-scale 2 x CYLINDER_RADIUS (m3c2's D "
            "and d are diameters), --max-depth CYLINDER_HALF_LENGTH (a half-length in both), --registration-error "
            "REGISTRATION_ERROR, --core-spacing SUBSAMPLING_CELL_SIZE (> 0; 0: every reference point), --orient +z "
            "(Up) or origin (Origin), --lod z and --variance population (PDAL's statistic), --field-names pdal "
            "--all-fields (PDAL's m3c2_* columns, m3c2_std_dev1 and 2 included, in LAS/LAZ too). The numbers differ "
            "from PDAL's where PDAL's are approximations: it stores counts as 16-bit integers (65535 at most; m3c2: "
            "exact); it multiplies by 1.96 (m3c2: the exact 95 % quantile 1.959964); it writes 0 where no distance "
            "can be computed (m3c2: NaN and a status column saying why); it runs on one thread (m3c2: every thread, "
            "the same bits for any count). CYLINDER_ORIENTATION None (the normal's sign left as the eigen solver "
            "gives it) has no m3c2 equivalent: m3c2 always orients normals (section 3.1.2) and refuses it. Use M3C2 "
            "compare for everything PDAL lacks: multi-scale normals, median, t and bootstrap LOD, M3C2-PM and EP, "
            "rasters.")

    def initAlgorithm(self, config=None):  # noqa: N802 - QGIS's name
        self.addParameter(cloud_parameter("INPUT", "Reference cloud (PDAL's first input)"))
        self.addParameter(cloud_parameter("INPUT_COMPARE", "Compared cloud (PDAL's second input)"))
        for name, label, default in NUMBERS:
            self.addParameter(QgsProcessingParameterNumber(name, label, type=DOUBLE, defaultValue=default, minValue=0.0))
        self.addParameter(QgsProcessingParameterEnum("CYLINDER_ORIENTATION", "Cylinder orientation (PDAL orientation)",
                                                     options=list(ORIENTATIONS), defaultValue=0))
        # Ours beyond QGIS 4's (optional: a pdal:compare model never sets them)
        self.addParameter(cloud_parameter("CORE", "Core points (PDAL's third input; default: every reference point)",
                                          optional=True))
        self.addParameter(QgsProcessingParameterNumber("MIN_POINTS", "Minimum points (PDAL min_points; m3c2 "
                                                       "--min-points)", type=INTEGER, defaultValue=1, minValue=1))
        self.addParameter(QgsProcessingParameterFileDestination("OUTPUT", "M3C2 output", OUTPUT_FILTER))
        self.addOutput(QgsProcessingOutputVectorLayer("OUTPUT_LAYER", "M3C2 result layer"))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802 - QGIS's name
        orientation = ORIENTATIONS[self.parameterAsEnum(parameters, "CYLINDER_ORIENTATION", context)]
        if orientation not in ORIENT:
            raise QgsProcessingException("CYLINDER_ORIENTATION None: m3c2 always orients the normals (section 3.1.2); "
                                         "choose Up (PDAL's default) or Origin, or M3C2 compare's ORIENTATION")
        number = lambda name: self.parameterAsDouble(parameters, name, context)  # noqa: E731
        output = self.output_path(parameters, "OUTPUT", context)
        args = ["compare", self.cloud_path(parameters, "INPUT", context),
                self.cloud_path(parameters, "INPUT_COMPARE", context), "-o", output]
        core = self.cloud_path(parameters, "CORE", context)
        cell = number("SUBSAMPLING_CELL_SIZE")
        if core and cell > 0:
            raise QgsProcessingException("give CORE or SUBSAMPLING_CELL_SIZE, not both: each chooses the core points")
        if core:
            args += ["--core", core]
        elif cell > 0:
            args += ["--core-spacing", repr(cell)]
        args += ["--normal-scale", repr(2.0 * number("NORMAL_RADIUS")),
                 "--projection-scale", repr(2.0 * number("CYLINDER_RADIUS")),
                 "--max-depth", repr(number("CYLINDER_HALF_LENGTH")),
                 "--registration-error", repr(number("REGISTRATION_ERROR")),
                 "--min-points", str(self.parameterAsInt(parameters, "MIN_POINTS", context)),
                 "--orient", ORIENT[orientation], "--lod", "z", "--variance", "population", "--field-names", "pdal",
                 "--all-fields"]
        self.m3c2(args + ["--progress", "json"], feedback, progress=True)
        return {"OUTPUT": output, "OUTPUT_LAYER": results.table_layer(output, feedback, context)}
