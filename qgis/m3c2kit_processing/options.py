"""Options of the m3c2 commands that are not compare's parameter table (c2c, classify apply,
series objects, suggest): each a QGIS parameter and its flag. All optional without a value of
their own: empty, the flag is not passed and m3c2's default applies (`m3c2 <command> --help`
states it). THREADS is the parameter table's row (table.py)."""
import json
import os
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


#: The options of the `m3c2 series` forms, generated from the command line's own parsers
#: (python -m m3c2kit.cli.forms_export): an algorithm built from it cannot drift from m3c2.
FORMS_FILE = os.path.join(os.path.dirname(__file__), "series_forms.json")
FORMS_FORMAT = 1


def _label(help_text: str, flag: str) -> str:
    """A dialog label from the option's help: its first clause, capitalised."""
    text = help_text.split(";")[0].split(" (")[0].strip() or flag.lstrip("-").replace("-", " ")
    return text[:1].upper() + text[1:]


def form_options(form: str) -> tuple:
    """The Opt of every option of `m3c2 series FORM` that the plugin offers (series_forms.json)."""
    with open(FORMS_FILE, encoding="utf-8") as f:
        doc = json.load(f)
    if doc.get("format") != FORMS_FORMAT:
        raise ValueError(f"{FORMS_FILE}: layout {doc.get('format')!r}, this plugin reads {FORMS_FORMAT}: "
                         "reinstall the plugin with its m3c2kit")
    return tuple(Opt(o["name"], o["flag"], o["type"], _label(o["help"], o["flag"]), tuple(o.get("choices") or ()),
                     o.get("minimum"), bool(o.get("required"))) for o in doc["forms"][form])
