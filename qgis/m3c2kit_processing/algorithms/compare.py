"""m3c2kit:compare, `m3c2 compare`: every compare parameter of the parameter table (table.py),
the command line's own inputs and outputs, the result loaded styled by distance."""
import os

from qgis.core import (QgsProcessingOutputFile, QgsProcessingOutputRasterLayer, QgsProcessingOutputVectorLayer,
                       QgsProcessingParameterBoolean, QgsProcessingParameterFile, QgsProcessingParameterFileDestination,
                       QgsProcessingParameterNumber, QgsProcessingParameterString)

from .. import results, table
from ..base import M3C2Algorithm, cloud_parameter
from ..compat import DOUBLE, FILE, advanced

OUTPUT_FILTER = "LAZ (*.laz);;LAS (*.las);;PLY (*.ply);;CSV (*.csv);;Text (*.txt)"
# --grid's rasters (m3c2kit.run.raster.raster_paths: <stem>_<name>.tif beside OUTPUT) shown as
# outputs: the QGIS output, the raster's name, drawn symmetric about 0.
RASTERS = (("DISTANCE_RASTER", "distance", True), ("LOD_RASTER", "lod", False),
           ("SIGNIFICANT_RASTER", "significant", False))


def raster_path(output, name):
    base = os.path.basename(output)
    stem = base[: -len(".copc.laz")] if base.lower().endswith(".copc.laz") else os.path.splitext(base)[0]
    return os.path.join(os.path.dirname(output), f"{stem}_{name}.tif")


class CompareAlgorithm(M3C2Algorithm):
    NAME = "compare"
    DISPLAY = "M3C2 compare"
    HELP = ("M3C2 change between REFERENCE and COMPARED at core points (Lague, Brodu & Leroux 2013), by the "
            "installed m3c2 command (m3c2 compare). D (NORMAL_SCALE) and d (PROJECTION_SCALE) are DIAMETERS; "
            "MAX_DEPTH is the cylinder's half-length. Empty parameters take m3c2's defaults. The output table "
            "(LAZ, LAS, PLY, CSV or TXT by extension) is loaded styled by distance; GRID_CELL also writes "
            "distance, LOD and significance rasters; the exact command line is in the log.")

    def initAlgorithm(self, config=None):  # noqa: N802 - QGIS's name
        self.addParameter(cloud_parameter("REFERENCE", "Reference cloud (first epoch)"))
        self.addParameter(cloud_parameter("COMPARED", "Compared cloud (second epoch)"))
        core = cloud_parameter("CORE", "Core points (default: every reference point, or CORE_SPACING)", optional=True)
        self.addParameter(core)
        grid = QgsProcessingParameterNumber("GRID_CELL", "2D mode: core points on a grid of this cell (--grid)",
                                            type=DOUBLE, defaultValue=None, optional=True, minValue=0.0)
        grid.setHelp("2D mode (section 6.1.2): core points on a CELL grid over the reference, vertical normals, d = "
                     "1.1 CELL unless PROJECTION_SCALE; also writes GeoTIFF rasters <stem>_distance.tif, _lod, "
                     "_significant, _n1, _n2, _status beside OUTPUT")
        self.addParameter(grid)
        for row in table.rows("compare"):
            self.addParameter(table.definition(row, grouped=True))
        own = (QgsProcessingParameterFile("CORE_NORMALS", "Core normals file (--core-normals)", behavior=FILE,
                                          optional=True),
               QgsProcessingParameterFile("PARAMS", "CloudCompare qM3C2 parameter file (--params)", behavior=FILE,
                                          optional=True),
               QgsProcessingParameterBoolean("PROJECTED", "Also write the projected positions x1..z2 (--projected)",
                                             defaultValue=False, optional=True),
               QgsProcessingParameterString("CRS", "CRS of inputs that have none (--crs)", optional=True),
               QgsProcessingParameterBoolean("IGNORE_CRS", "Compare clouds whose CRSs differ (--ignore-crs)",
                                             defaultValue=False, optional=True),
               QgsProcessingParameterNumber("TILE_SIZE", "Out-of-core tiles of this side (--tile-size)", type=DOUBLE,
                                            defaultValue=None, optional=True, minValue=0.0))
        for param in own:
            self.addParameter(advanced(param))
        self.addParameter(QgsProcessingParameterFileDestination("OUTPUT", "M3C2 output (LAZ, LAS, PLY, CSV, TXT)",
                                                                OUTPUT_FILTER))
        self.addParameter(QgsProcessingParameterFileDestination("REPORT", "HTML report (--report)",
                                                                "HTML (*.html)", optional=True,
                                                                createByDefault=False))
        self.addOutput(QgsProcessingOutputVectorLayer("OUTPUT_LAYER", "M3C2 result layer"))
        for output, name, _ in RASTERS:
            self.addOutput(QgsProcessingOutputRasterLayer(output, f"{name} raster (with GRID_CELL)"))
        self.addOutput(QgsProcessingOutputFile("REPORT_FILE", "HTML report"))

    def command_arguments(self, parameters, context):
        """m3c2 compare's arguments for `parameters` (the command line logged and run)."""
        output = self.output_path(parameters, "OUTPUT", context)
        args = ["compare", self.cloud_path(parameters, "REFERENCE", context),
                self.cloud_path(parameters, "COMPARED", context), "-o", output]
        core = self.cloud_path(parameters, "CORE", context)
        if core:
            args += ["--core", core]
        if parameters.get("GRID_CELL") is not None:
            args += ["--grid", repr(self.parameterAsDouble(parameters, "GRID_CELL", context))]
        for row in table.rows("compare"):
            args += table.arguments(self, row, parameters, context)
        for name, flag in (("CORE_NORMALS", "--core-normals"), ("PARAMS", "--params"), ("CRS", "--crs")):
            value = self.parameterAsString(parameters, name, context)
            if value:
                args += [flag, value]
        for name, flag in (("PROJECTED", "--projected"), ("IGNORE_CRS", "--ignore-crs")):
            if parameters.get(name) is not None and self.parameterAsBool(parameters, name, context):
                args.append(flag)
        if parameters.get("TILE_SIZE") is not None:
            args += ["--tile-size", repr(self.parameterAsDouble(parameters, "TILE_SIZE", context))]
        report = self.output_path(parameters, "REPORT", context) if parameters.get("REPORT") else ""
        if report:
            args += ["--report", report]
        return args, output, report

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802 - QGIS's name
        args, output, report = self.command_arguments(parameters, context)
        self.m3c2(args + ["--progress", "json"], feedback, progress=True)
        outputs = {"OUTPUT": output, "REPORT_FILE": report or None}
        outputs["OUTPUT_LAYER"] = results.table_layer(output, feedback, context)
        if parameters.get("GRID_CELL") is not None:
            for key, name, symmetric in RASTERS:
                path = raster_path(output, name)
                outputs[key] = path
                results.raster_layer(path, context, key, symmetric)
        return outputs
