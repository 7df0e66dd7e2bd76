"""Results into the project: m3c2 compare's point table as a layer styled by distance, and its
rasters. Where QGIS reads LAZ (its 'pdal' provider: QGIS 4, or 3.x built with PDAL) a LAS/LAZ
output is loaded as a point-cloud layer; elsewhere (Debian 12's QGIS 3.22 has no PDAL) as a
vector point layer in a GeoPackage beside the output (OUTPUT + '.gpkg', written by QGIS's own
writer) holding every column, its style saved in it as the default."""
import csv
import json
import math
import os
import re

from qgis.core import (Qgis, QgsCoordinateReferenceSystem, QgsFeature, QgsField, QgsFields, QgsGeometry, QgsPoint,
                       QgsProcessingContext, QgsProcessingLayerPostProcessorInterface, QgsProcessingUtils,
                       QgsProject, QgsProviderRegistry, QgsVectorFileWriter, QgsVectorLayer)

from . import runner, style

POINT_CLOUD_EXTENSIONS = (".las", ".laz")
_KEPT = []  # post-processors must outlive processAlgorithm (QGIS holds no Python reference)


def reads_point_clouds() -> bool:
    """True where QGIS can open LAS/LAZ as a point-cloud layer (its 'pdal' provider)."""
    return "pdal" in QgsProviderRegistry.instance().providerList()


def _field(name, integer: bool):
    """A Double field, or an Int one for a column of whole numbers (counts, flags, status codes)."""
    if Qgis.QGIS_VERSION_INT >= 33800:  # QgsField takes a QMetaType from 3.38 on (QGIS 4: only it)
        from qgis.PyQt.QtCore import QMetaType
        return QgsField(name, QMetaType.Type.Int if integer else QMetaType.Type.Double)
    from qgis.PyQt.QtCore import QVariant
    return QgsField(name, QVariant.Int if integer else QVariant.Double)


def _number(text):
    value = float(text)
    return None if math.isnan(value) else value


INT_LIMIT = 2**31  # QGIS's Int field


def _whole(values) -> bool:
    """Whether a column holds whole numbers only (NULL aside) that an Int field holds: m3c2's
    counts, flags and status codes stay integers in the layer (issue 44: every column was Real)."""
    return all(v is None or (v.is_integer() and abs(v) < INT_LIMIT) for v in values)


def geopackage_path(output) -> str:
    return f"{output}.gpkg"


def layer_name(file_name: str) -> str:
    """A GeoPackage layer name for the output `file_name`: OGR refuses names with special characters
    or a leading '-' ('-out.laz' failed after the run: "may not contain special characters")."""
    stem = re.sub(r"[^0-9A-Za-z_]", "_", os.path.splitext(file_name)[0])
    return stem if stem[:1].isalpha() else f"m3c2_{stem}"


def write_geopackage(output, feedback, context) -> str:
    """OUTPUT + '.gpkg': every column of the m3c2 output `output`, one point per row, styled."""
    # QGIS's Python has no m3c2kit: m3c2 itself copies the output into a CSV (every column, float64
    # written losslessly) and says its CRS.
    table = QgsProcessingUtils.generateTempFilename("m3c2kit_table.csv")
    # Internal runs: their command lines are logged, their outputs (a copy's summary, JSON) are not.
    runner.run(["convert", runner.path_argument(output), "-o", table, "-q"], feedback, echo=False)
    info = runner.run(["info", "--json", runner.path_argument(output)], feedback, echo=False)
    wkt = (json.loads(info).get("crs") or {}).get("wkt") or ""
    name = os.path.basename(str(output))
    memory = QgsVectorLayer("PointZ", name, "memory")
    if wkt:
        memory.setCrs(QgsCoordinateReferenceSystem.fromWkt(wkt))
    with open(table, newline="", encoding="utf-8") as f:
        rows = csv.reader(f)
        header = next(rows)
        data = [[_number(v) for v in row] for row in rows]
    whole = [_whole(column) for column in zip(*data)] if data else [False] * len(header)
    fields = QgsFields()
    for column, integer in zip(header, whole):
        fields.append(_field(column, integer))
    memory.dataProvider().addAttributes(fields.toList())
    memory.updateFields()
    features = []
    for values in data:
        feature = QgsFeature(memory.fields())
        x, y, z = (math.nan if v is None else v for v in values[:3])  # a row without a position: NaN
        feature.setGeometry(QgsGeometry(QgsPoint(x, y, z)))
        feature.setAttributes([v if v is None or not integer else int(v) for v, integer in zip(values, whole)])
        features.append(feature)
    memory.dataProvider().addFeatures(features)
    os.remove(table)
    path = geopackage_path(output)
    options = QgsVectorFileWriter.SaveVectorOptions()
    options.driverName = "GPKG"
    options.layerName = layer_name(name)
    error = QgsVectorFileWriter.writeAsVectorFormatV3(memory, path, context.transformContext(), options)
    if error[0] != QgsVectorFileWriter.NoError:
        raise runner.QgsProcessingException(f"{path}: cannot write the GeoPackage: {error[1]}")
    layer = QgsVectorLayer(path, options.layerName, "ogr")
    if style.style_points(layer):
        message = layer.saveStyleToDatabase("m3c2kit", "distance on a diverging ramp, not-significant faded",
                                            True, "")
        if message:
            feedback.pushWarning(f"{path}: style not saved in the GeoPackage: {message}")
    return path


class _Styler(QgsProcessingLayerPostProcessorInterface):
    def __init__(self, apply):
        super().__init__()
        self.apply = apply

    def postProcessLayer(self, layer, context, feedback):  # noqa: N802 - QGIS's name
        self.apply(layer)


def load_on_completion(context, source, name, output_name, apply):
    """`source` loaded into the project when the algorithm ends, then styled by `apply(layer)`."""
    project = context.project() or QgsProject.instance()
    details = QgsProcessingContext.LayerDetails(name, project, output_name)
    styler = _Styler(apply)
    _KEPT.append(styler)
    details.setPostProcessor(styler)
    context.addLayerToLoadOnCompletion(source, details)


def _point_cloud_bound(layer):
    try:  # QGIS >= 3.26: statistics of the attribute
        stats = layer.statistics()
        names = [a.name() for a in layer.attributes().attributes()]
        distance = style.field_named(names, style.DISTANCE_NAMES)
        return style.symmetric_bound([stats.minimum(distance), stats.maximum(distance)])
    except Exception:  # noqa: BLE001 - older QGIS: a unit range, which the user can reclassify
        return 1.0


def table_layer(output, feedback, context, output_name="OUTPUT_LAYER"):
    """The layer of m3c2's point table `output`, loaded on completion; its source."""
    name = os.path.basename(str(output))
    if reads_point_clouds() and str(output).lower().endswith(POINT_CLOUD_EXTENSIONS):
        load_on_completion(context, str(output), name, output_name,
                           lambda layer: style.style_point_cloud(layer, _point_cloud_bound(layer)))
        return str(output)
    path = write_geopackage(output, feedback, context)
    load_on_completion(context, path, name, output_name, style.style_points)
    return path


def raster_layer(path, context, output_name, symmetric):
    load_on_completion(context, str(path), os.path.basename(str(path)), output_name,
                       lambda layer: style.style_raster(layer, symmetric))
