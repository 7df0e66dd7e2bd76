"""How results look: the distance on a diverging ramp centred on 0 (ColorBrewer RdBu reversed:
lowering blue, raising red), classes symmetric about 0, points whose change is not significant
faded; rasters with the same ramp."""
import math

from qgis.core import (QgsColorRampShader, QgsGradientColorRamp, QgsGradientStop, QgsGraduatedSymbolRenderer,
                       QgsProperty, QgsRasterShader, QgsRendererRange, QgsSingleBandPseudoColorRenderer,
                       QgsSymbol)
from qgis.PyQt.QtGui import QColor

from .compat import INTERPOLATED, MIN_MAX

# ColorBrewer RdBu (11 classes), reversed: the most negative distance first.
RAMP_COLOURS = ("#053061", "#2166ac", "#4393c3", "#92c5de", "#d1e5f0", "#f7f7f7", "#fddbc7", "#f4a582", "#d6604d",
                "#b2182b", "#67001f")
CLASSES = 10  # even: 0 is a class boundary, as many classes below as above
INNER_QUANTILE = 0.95  # of |distance|: where the inner classes end (class_edges)
FADED_OPACITY = 25  # percent, for points whose |distance| <= LOD (or without a LOD)
DISTANCE_NAMES = ("distance", "m3c2_distance", "M3C2 distance", "M3C2_distance")
SIGNIFICANT_NAMES = ("significant", "m3c2_significant", "significant change", "significant_change")


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


def class_edges(values):
    """CLASSES + 1 edges symmetric about 0, 0 the middle one: the inner ones spread over
    [-b, b], b the INNER_QUANTILE of |value| (a few large changes would otherwise leave every
    class but the outer two nearly empty), the outer two reaching the largest |value|."""
    finite = _finite_abs(values)
    top = finite[-1] if finite and finite[-1] > 0 else 1.0
    inner = finite[min(len(finite) - 1, int(INNER_QUANTILE * len(finite)))] if finite else top
    inner = inner if 0 < inner < top else top * (CLASSES // 2 - 1) / (CLASSES // 2)  # equal classes
    half = CLASSES // 2
    steps = [-inner + i * inner / (half - 1) for i in range(half - 1)] + [0.0]
    steps += [-v for v in reversed(steps[:-1])]
    return [-top] + steps + [top] if CLASSES > 2 else [-top, 0.0, top]


def field_named(names, candidates):
    for name in candidates:
        if name in names:
            return name
    return None


def _opacity_property():
    legacy = getattr(QgsSymbol, "PropertyOpacity", None)
    return legacy if legacy is not None else QgsSymbol.Property.Opacity


def graduated_renderer(distance_field, significant_field, edges, geometry_symbol):
    """Classes of `distance_field` between `edges` (class_edges); with `significant_field`, each
    class's symbol faded where it is not 1."""
    colours = ramp()
    ranges = []
    for i, (lower, upper) in enumerate(zip(edges[:-1], edges[1:])):
        symbol = geometry_symbol.clone()
        symbol.setColor(colours.color((i + 0.5) / (len(edges) - 1)))
        if significant_field is not None:
            symbol.setDataDefinedProperty(_opacity_property(), QgsProperty.fromExpression(
                f'if("{significant_field}" = 1, 100, {FADED_OPACITY})'))
        ranges.append(QgsRendererRange(lower, upper, symbol, f"{lower:.3g} to {upper:.3g}"))
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
    edges = class_edges([f.attribute(index) for f in layer.getFeatures()])
    symbol = QgsSymbol.defaultSymbol(layer.geometryType())
    symbol.setSize(1.8)
    if hasattr(symbol, "symbolLayer") and symbol.symbolLayerCount():
        symbol.symbolLayer(0).setStrokeStyle(0)  # no outline: neighbouring points stay readable
    layer.setRenderer(graduated_renderer(distance, field_named(names, SIGNIFICANT_NAMES), edges, symbol))
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
