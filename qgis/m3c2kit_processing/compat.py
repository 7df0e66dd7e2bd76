"""The enum values this plugin uses, spelled the QGIS >= 3.36 way (Qgis.* scoped enums, the only
spelling QGIS 4 keeps) with the QGIS 3.22 spelling as the fallback."""
from qgis.core import (Qgis, QgsProcessingAlgorithm, QgsProcessingParameterDefinition, QgsProcessingParameterFile,
                       QgsProcessingParameterNumber)


def _pick(scoped: str, member: str, owner, legacy: str):
    enum = getattr(Qgis, scoped, None)
    if enum is not None and hasattr(enum, member):
        return getattr(enum, member)
    return getattr(owner, legacy)


DOUBLE = _pick("ProcessingNumberParameterType", "Double", QgsProcessingParameterNumber, "Double")
INTEGER = _pick("ProcessingNumberParameterType", "Integer", QgsProcessingParameterNumber, "Integer")
ADVANCED = _pick("ProcessingParameterFlag", "Advanced", QgsProcessingParameterDefinition, "FlagAdvanced")
OPTIONAL = _pick("ProcessingParameterFlag", "Optional", QgsProcessingParameterDefinition, "FlagOptional")
FILE = _pick("ProcessingFileParameterBehavior", "File", QgsProcessingParameterFile, "File")
FOLDER = _pick("ProcessingFileParameterBehavior", "Folder", QgsProcessingParameterFile, "Folder")
# m3c2 is a separate process: QGIS may run the algorithm in a background thread, but it must not
# start several from one algorithm instance at once (the default), nothing else to declare.
NO_THREADING = _pick("ProcessingAlgorithmFlag", "NoThreading", QgsProcessingAlgorithm, "FlagNoThreading")


def advanced(param):
    """`param` shown under the dialog's "Advanced parameters"."""
    param.setFlags(param.flags() | ADVANCED)
    return param


def _late():
    """Enums of classes outside qgis.core's processing part."""
    from qgis.core import QgsColorRampShader, QgsRasterBandStats
    linear = _pick("ShaderInterpolationMethod", "Linear", QgsColorRampShader, "Interpolated")
    stats = _pick("RasterBandStatistic", "Min", QgsRasterBandStats, "Min") | _pick("RasterBandStatistic", "Max",
                                                                                   QgsRasterBandStats, "Max")
    return linear, stats


INTERPOLATED, MIN_MAX = _late()
