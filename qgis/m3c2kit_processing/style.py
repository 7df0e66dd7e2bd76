"""How results look: the distance on a diverging ramp centred on 0 (ColorBrewer RdBu reversed:
lowering blue, raising red), classes symmetric about 0 around one neutral grey class |d| <= the
layer's median LOD ("no significant change", not "no data"), labelled in the layer's unit; points
of the other classes whose change is not significant half faded; rasters with the same ramp."""
import math

from qgis.core import (QgsColorRampShader, QgsGradientColorRamp, QgsGradientStop, QgsGraduatedSymbolRenderer,
                       QgsProperty, QgsRasterShader, QgsRendererRange, QgsSingleBandPseudoColorRenderer,
                       QgsSymbol)
from qgis.PyQt.QtGui import QColor

from .compat import INTERPOLATED, MIN_MAX

# ColorBrewer RdBu (11 classes), reversed: the most negative distance first.
RAMP_COLOURS = ("#053061", "#2166ac", "#4393c3", "#92c5de", "#d1e5f0", "#f7f7f7", "#fddbc7", "#f4a582", "#d6604d",
                "#b2182b", "#67001f")
CLASSES = 11  # odd: one neutral class around 0, as many classes below as above
INNER_QUANTILE = 0.95  # of |distance|: where the inner classes end (class_edges)
FADED_OPACITY = 45  # percent, for points outside the neutral class whose change is not significant
NEUTRAL_COLOUR = "#bdbdbd"  # a grey that reads as "no significant change", opaque: never "no data"
DISTANCE_NAMES = ("distance", "m3c2_distance", "M3C2 distance", "M3C2_distance")
SIGNIFICANT_NAMES = ("significant", "m3c2_significant", "significant change", "significant_change")
LOD_NAMES = ("lod", "m3c2_lod", "distance uncertainty", "Distance__uncertainty")


def ramp() -> QgsGradientColorRamp:
    first, last = QColor(RAMP_COLOURS[0]), QColor(RAMP_COLOURS[-1])
    n = len(RAMP_COLOURS) - 1
    stops = [QgsGradientStop(i / n, QColor(c)) for i, c in enumerate(RAMP_COLOURS[1:-1], start=1)]
    return QgsGradientColorRamp(first, last, False, stops)


def symmetric_bound(values) -> float:
    """The largest finite |value| (1 when there is none): the ramp runs from -bound to +bound."""
    finite = _finite_abs(values)
    return finite[-1] if finite and finite[-1] > 0 else 1.0


def _finite_abs(values):
    return sorted(abs(v) for v in values if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v))


def typical_lod(values):
    """The median finite LOD > 0 of the layer, None without one: the neutral class's half-width."""
    finite = [v for v in _finite_abs(values) if v > 0]
    return finite[len(finite) // 2] if finite else None


def class_edges(values, lod=None):
    """CLASSES + 1 edges symmetric about 0 around a neutral middle class [-c, c], c the typical
    LOD (typical_lod) or, without one, the inner bound / (CLASSES // 2): the other inner classes
    spread evenly from c to b, b the INNER_QUANTILE of |value| (a few large changes would
    otherwise leave every class but the outer two nearly empty), the outer two reaching the
    largest |value|."""
    finite = _finite_abs(values)
    half = CLASSES // 2
    top = finite[-1] if finite and finite[-1] > 0 else 1.0
    inner = finite[min(len(finite) - 1, int(INNER_QUANTILE * len(finite)))] if finite else top
    inner = inner if 0 < inner < top else top * (half - 1) / half  # equal classes
    centre = lod if lod is not None and 0 < lod < inner else inner / half
    positive = [centre + k * (inner - centre) / (half - 1) for k in range(half)] + [top]
    return [-v for v in reversed(positive)] + positive


def unit_of(layer) -> str:
    """The layer's distance unit in words for the legend: its projected CRS's map unit ("m",
    "ft"), else "" (the data's own unit, unknown): a geographic CRS is what a layer without one
    is given (EPSG:4326), and degrees are never an M3C2 distance's unit."""
    try:
        from qgis.core import QgsUnitTypes
        crs = layer.crs()
        if not crs.isValid() or crs.isGeographic():
            return ""
        return QgsUnitTypes.toAbbreviatedString(crs.mapUnits())
    except (AttributeError, TypeError):
        return ""


def class_labels(edges, unit, from_lod):
    """The legend's label of each class: signed ranges in the unit; the neutral one says what it is."""
    suffix = f" {unit}" if unit else ""
    labels = [f"{lower:+.3g} to {upper:+.3g}{suffix}" for lower, upper in zip(edges[:-1], edges[1:])]
    middle = len(labels) // 2
    centre = edges[middle + 1]
    what = "within the typical LOD: no significant change" if from_lod else "near 0"
    labels[middle] = f"|d| <= {centre:.3g}{suffix} ({what})"
    return labels


def field_named(names, candidates):
    for name in candidates:
        if name in names:
            return name
    return None


def _opacity_property():
    legacy = getattr(QgsSymbol, "PropertyOpacity", None)
    return legacy if legacy is not None else QgsSymbol.Property.Opacity


def graduated_renderer(distance_field, significant_field, edges, geometry_symbol, labels=None):
    """Classes of `distance_field` between `edges` (class_edges), labelled `labels`
    (class_labels); the middle class neutral grey and opaque; with `significant_field`, each other
    class's symbol faded where it is not 1."""
    colours = ramp()
    ranges = []
    middle = (len(edges) - 1) // 2
    for i, (lower, upper) in enumerate(zip(edges[:-1], edges[1:])):
        symbol = geometry_symbol.clone()
        if i == middle:
            symbol.setColor(QColor(NEUTRAL_COLOUR))
        else:
            symbol.setColor(colours.color((i + 0.5) / (len(edges) - 1)))
            if significant_field is not None:
                symbol.setDataDefinedProperty(_opacity_property(), QgsProperty.fromExpression(
                    f'if("{significant_field}" = 1, 100, {FADED_OPACITY})'))
        label = labels[i] if labels is not None else f"{lower:+.3g} to {upper:+.3g}"
        ranges.append(QgsRendererRange(lower, upper, symbol, label))
    renderer = QgsGraduatedSymbolRenderer(distance_field, ranges)
    renderer.setSourceColorRamp(colours)
    return renderer


def style_points(layer):
    """A vector point layer of m3c2 compare's columns, styled by distance (returns False when it
    has no distance column)."""
    names = [f.name() for f in layer.fields()]
    distance = field_named(names, DISTANCE_NAMES)
    if distance is None:
        return False
    index = layer.fields().indexOf(distance)
    lod_field = field_named(names, LOD_NAMES)
    lod = None
    if lod_field is not None:
        lod_index = layer.fields().indexOf(lod_field)
        lod = typical_lod([f.attribute(lod_index) for f in layer.getFeatures()])
    edges = class_edges([f.attribute(index) for f in layer.getFeatures()], lod)
    labels = class_labels(edges, unit_of(layer), lod is not None and edges[CLASSES // 2 + 1] == lod)
    symbol = QgsSymbol.defaultSymbol(layer.geometryType())
    symbol.setSize(1.8)
    if hasattr(symbol, "symbolLayer") and symbol.symbolLayerCount():
        symbol.symbolLayer(0).setStrokeStyle(0)  # no outline: neighbouring points stay readable
    layer.setRenderer(graduated_renderer(distance, field_named(names, SIGNIFICANT_NAMES), edges, symbol, labels))
    layer.triggerRepaint()
    return True


def _shader(lo, hi):
    function = QgsColorRampShader(lo, hi, ramp(), INTERPOLATED)
    function.classifyColorRamp(len(RAMP_COLOURS), -1)
    shader = QgsRasterShader()
    shader.setRasterShaderFunction(function)
    return shader


def style_raster(layer, symmetric=True):
    """Band 1 on the ramp: from -bound to +bound (the distance), or over its range (LOD, significant)."""
    stats = layer.dataProvider().bandStatistics(1, MIN_MAX)
    lo, hi = stats.minimumValue, stats.maximumValue
    if not (math.isfinite(lo) and math.isfinite(hi)):
        lo, hi = -1.0, 1.0
    if symmetric:
        hi = symmetric_bound([lo, hi])
        lo = -hi
    elif hi <= lo:
        hi = lo + 1.0
    renderer = QgsSingleBandPseudoColorRenderer(layer.dataProvider(), 1, _shader(lo, hi))
    renderer.setClassificationMin(lo)
    renderer.setClassificationMax(hi)
    layer.setRenderer(renderer)
    layer.triggerRepaint()
    return True


def style_point_cloud(layer, bound):
    """A point-cloud layer (QGIS with PDAL): the distance attribute on the ramp, -bound to +bound.
    QGIS's point-cloud renderers have no per-point opacity, so not-significant points are not faded
    there (the vector layer fades them)."""
    from qgis.core import QgsPointCloudAttributeByRampRenderer
    names = [a.name() for a in layer.attributes().attributes()]
    distance = field_named(names, DISTANCE_NAMES)
    if distance is None:
        return False
    function = QgsColorRampShader(-bound, bound, ramp(), INTERPOLATED)
    function.classifyColorRamp(len(RAMP_COLOURS), -1)
    renderer = QgsPointCloudAttributeByRampRenderer()
    renderer.setAttribute(distance)
    renderer.setColorRampShader(function)
    renderer.setMinimum(-bound)
    renderer.setMaximum(bound)
    layer.setRenderer(renderer)
    layer.triggerRepaint()
    return True
