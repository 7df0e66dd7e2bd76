"""Parameters: the one table (:mod:`.table`), the checking and defaults derived from it
(:mod:`.resolve`), the CloudCompare params file (:mod:`.cloudcompare_params`) and the docs'
option table (:mod:`.docs`). Layer: imports errors, io and engine only (docs/architecture.md)."""
from .resolve import build_params, check_keywords, engine_params, resolve
from .table import PARAMETERS, Parameter, by_name, parameters_of

__all__ = ["PARAMETERS", "Parameter", "by_name", "parameters_of", "build_params", "check_keywords", "engine_params", "resolve"]
