"""Options of the m3c2 commands that are not in the parameter table (c2c, classify apply,
suggest): each a QGIS parameter and its flag. All optional without a value of
their own: empty, the flag is not passed and m3c2's default applies (`m3c2 <command> --help`
states it). THREADS is the parameter table's row (table.py)."""
from dataclasses import dataclass

from qgis.core import (QgsProcessingParameterBoolean, QgsProcessingParameterEnum, QgsProcessingParameterFile,
                       QgsProcessingParameterNumber, QgsProcessingParameterString)

from . import table
from .compat import DOUBLE, FILE, INTEGER


@dataclass(frozen=True)
class Opt:
    name: str
    flag: str
    kind: str  # "real", "integer", "flag", "choice", "text", "file"
    label: str
    choices: tuple = ()
    minimum: float = None
    required: bool = False

    def definition(self):
        label, optional = f"{self.label} ({self.flag})", not self.required
        if self.kind == "flag":
            return QgsProcessingParameterBoolean(self.name, label, defaultValue=False, optional=True)
        if self.kind == "choice":
            return QgsProcessingParameterEnum(self.name, label, options=list(self.choices), defaultValue=None,
                                              optional=optional)
        if self.kind in ("real", "integer"):
            param = QgsProcessingParameterNumber(self.name, label, type=INTEGER if self.kind == "integer" else DOUBLE,
                                                 defaultValue=None, optional=optional)
            if self.minimum is not None:
                param.setMinimum(self.minimum)
            return param
        if self.kind == "file":
            return QgsProcessingParameterFile(self.name, label, behavior=FILE, optional=optional)
        return QgsProcessingParameterString(self.name, label, optional=optional)

    def arguments(self, algorithm, parameters, context):
        if parameters.get(self.name) is None:
            return []
        if self.kind == "flag":
            return [self.flag] if algorithm.parameterAsBool(parameters, self.name, context) else []
        if self.kind == "choice":
            return [self.flag, self.choices[algorithm.parameterAsEnum(parameters, self.name, context)]]
        if self.kind == "integer":
            return [self.flag, str(algorithm.parameterAsInt(parameters, self.name, context))]
        if self.kind == "real":
            return [self.flag, repr(algorithm.parameterAsDouble(parameters, self.name, context))]
        text = algorithm.parameterAsString(parameters, self.name, context)
        return [self.flag, text] if text else []


def threads():
    """THREADS, the parameter table's --threads row."""
    row = next(r for r in table.rows("compare") if r["name"] == "threads")
    return table.definition(row), row


def threads_arguments(algorithm, parameters, context):
    _, row = threads()
    return table.arguments(algorithm, row, parameters, context)
