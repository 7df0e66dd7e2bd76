"""m3c2 compare's parameters (and the series steps') in QGIS, from parameters.json: the parameter table of m3c2kit
(python/m3c2kit/settings/table.py, its one owner), exported by
`python -m m3c2kit.settings.export qgis/m3c2kit_processing/parameters.json`. A row added to the
table reaches this dialog by regenerating the file; only its QGIS name may need a line in NAMES.

Every parameter is optional with no value of its own: left empty, its flag is not passed and m3c2
applies its default (which --compat cloudcompare may change), as on the command line. Lists,
ranges, orientations and files are strings passed verbatim; m3c2 checks them and its message
reaches the Processing log."""
import json
import os

from qgis.core import (QgsProcessingException, QgsProcessingParameterBoolean, QgsProcessingParameterEnum,
                       QgsProcessingParameterFile, QgsProcessingParameterNumber, QgsProcessingParameterString)

from .compat import DOUBLE, FILE, INTEGER, advanced

PATH = os.path.join(os.path.dirname(__file__), "parameters.json")
FORMAT = 1
INT_MAX = 2**31 - 1  # QGIS's integer parameter is an int

# The QGIS names that are not the table's name in capitals (issue 33's contract).
NAMES = {"orient": "ORIENTATION"}
# In the dialog's main part; the others are "Advanced parameters".
MAIN = ("normal_scale", "projection_scale", "max_depth", "registration_error", "orient", "normal_source", "median",
        "confidence", "lod", "core_spacing", "classifier", "keep", "threads",
        "use", "neighbourhood_radius", "min_period", "height_threshold", "min_segments",  # series objects'
        "max_distance")  # register's

# Rows the compare algorithm leaves out, and why: an alias of another row.
LEFT_OUT = {"t_statistic": "the same as LOD = auto"}


def rows(command="compare"):
    with open(PATH, encoding="utf-8") as f:
        data = json.load(f)
    if data.get("format") != FORMAT:
        raise QgsProcessingException(f"{PATH}: format {data.get('format')!r}, this plugin reads {FORMAT}: "
                                     "regenerate it with python -m m3c2kit.settings.export")
    chosen = [r for r in data["parameters"] if command in r["commands"] and r["name"] not in LEFT_OUT]
    # By group (CloudCompare's tabs, in the file's order; QGIS has no tabs), the table's order within one.
    order = {group: rank for rank, group in enumerate(data.get("groups") or ())}
    return sorted(chosen, key=lambda r: order.get(r.get("group"), len(order)))


def qgis_name(row) -> str:
    return NAMES.get(row["name"], row["name"].upper())


def title(row, grouped=False) -> str:
    """The row's label (the parameter table's, in words; its flag is in the help); `grouped` (the
    compare dialog): after its group's name ("Scales: Normal scale D (diameter)")."""
    label = row.get("label") or row["name"].replace("_", " ").capitalize()
    return f"{row['group']}: {label}" if grouped and row.get("group") else label


def help_text(row) -> str:
    return f"{row['help']}. Range: {row['range']}. Default: {row['default_text']}. m3c2 option: {row['flag']}."


def _is_file(row) -> bool:
    metavar = row.get("metavar") or ""
    return metavar == "FILE" or metavar.endswith(".json")


def definition(row, grouped=False):
    """The QGIS parameter of one table row (`grouped`: its label after its group's name, title())."""
    name, label, kind = qgis_name(row), title(row, grouped), row["type"]
    if kind == "flag":
        param = QgsProcessingParameterBoolean(name, label, defaultValue=False, optional=True)
    elif kind == "choice":
        param = QgsProcessingParameterEnum(name, label, options=row["choices"], allowMultiple=False,
                                           defaultValue=None, optional=True)
    elif kind in ("real", "integer"):
        integer = kind == "integer"
        param = QgsProcessingParameterNumber(name, label, type=INTEGER if integer else DOUBLE, defaultValue=None,
                                             optional=True)
        param.setMinimum(row["minimum"])
        if integer:
            param.setMaximum(min(row["maximum"], INT_MAX))
        elif row.get("below") is not None:
            param.setMaximum(row["below"])
    elif _is_file(row):
        param = QgsProcessingParameterFile(name, label, behavior=FILE, optional=True)
    else:
        param = QgsProcessingParameterString(name, label, optional=True)
    param.setHelp(help_text(row))
    return param if row["name"] in MAIN else advanced(param)


def arguments(algorithm, row, parameters, context) -> list:
    """The row's flag and value when the user gave one."""
    name, kind = qgis_name(row), row["type"]
    if name not in parameters or parameters[name] is None:
        return []
    if kind == "flag":
        return [row["flag"]] if algorithm.parameterAsBool(parameters, name, context) else []
    if kind == "choice":
        return [row["flag"], row["choices"][algorithm.parameterAsEnum(parameters, name, context)]]
    if kind == "integer":
        return [row["flag"], str(algorithm.parameterAsInt(parameters, name, context))]
    if kind == "real":
        return [row["flag"], repr(algorithm.parameterAsDouble(parameters, name, context))]
    text = algorithm.parameterAsString(parameters, name, context)
    return [row["flag"], text] if text != "" else []
