"""QGIS plugin m3c2kit_processing: the Processing provider `m3c2kit` (docs/qgis.md)."""


def classFactory(iface):  # noqa: N802 - QGIS's plugin entry point
    from .plugin import M3C2kitPlugin
    return M3C2kitPlugin(iface)
