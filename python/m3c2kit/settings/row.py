"""One row of the parameter table (:mod:`.table`): a user-facing parameter, its flag, range,
default and the engine field(s) it sets. A row's default is read from the engine struct it sets
(Params, or a series step's ObjectsParams, Tam3c2Params, KalmanParams) unless the row gives its
own: a default is written in one place, the C++ struct's or the row's."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

from .. import engine
from .needs import Needs
from .parsers import Choice

__all__ = ["FROM_ENGINE", "SAME", "EngineField", "Parameter", "same", "enum", "unset_is_zero"]

FROM_ENGINE = "<the engine's default>"
SAME = "<the same>"


@dataclass(frozen=True)
class EngineField:
    """How a parameter's value becomes fields of the engine struct `struct`, and back (for its
    default): `from_engine` reads engine.default_fields(struct)."""

    fields: tuple[str, ...]
    to_engine: Callable[..., dict]
    from_engine: Callable[[dict], Any]
    struct: str = "Params"


def same(field: str, struct: str = "Params") -> EngineField:
    """The value is the engine field's."""
    return EngineField((field,), lambda v, **_: {field: v}, lambda f: f[field], struct)


def enum(field: str, struct: str = "Params") -> EngineField:
    """A choice spelled with '-' for the engine enum member spelled with '_'."""
    return EngineField((field,), lambda v, **_: {field: v.replace("-", "_")},
                       lambda f: f[field].replace("_", "-"), struct)


def unset_is_zero(field: str, zero: Any = 0.0) -> EngineField:
    """None (not given) is the engine's `zero`, which means off."""
    return EngineField((field,), lambda v, **_: {field: zero if v is None else v},
                       lambda f: f[field] or None)


@dataclass(frozen=True)
class Parameter:
    """One user-facing parameter. `kind(flag, value)` checks a value (its range: kind.describe());
    `cli_type` is argparse's type (None: an on/off flag); `commands` the subcommands that take it."""

    name: str
    flag: str
    kind: Callable
    help: str
    section: str
    engine: EngineField | None = None
    default: Any = FROM_ENGINE
    cloudcompare: Any = SAME
    cloudcompare_keys: tuple[str, ...] = ()
    py4dgeo: str = ""
    cli_type: Callable | None = float
    metavar: str | None = None
    commands: tuple[str, ...] = ("compare",)
    # "engine": sets Params fields; "run": how the run is made; "output": how it is written;
    # "series": an option of a series step (its value taken as checked: no resolve step follows)
    scope: str = "engine"
    needs: tuple[Needs, ...] = ()  # when it acts (m3c2kit.settings.needs): given where one fails, a usage error
    unset: str = ""  # what not giving it means, in words, where its default is none ("the store's")
    label: str = ""  # a dialog's name for it (QGIS); its name in words when empty

    def title(self) -> str:
        """What a dialog calls it: the label, else the name in words."""
        return self.label or self.name.replace("_", " ").capitalize()

    def default_for(self, compat: str | None = None):
        """The default, under --compat cloudcompare when `compat` says so."""
        if compat == "cloudcompare" and self.cloudcompare is not SAME:
            return self.cloudcompare
        if self.default is FROM_ENGINE:
            return self.engine.from_engine(engine.default_fields(self.engine.struct))
        return self.default

    @property
    def choices(self):
        return self.kind.values if isinstance(self.kind, Choice) else None

    def default_text(self) -> str:
        """The default in words: its value, or what not giving it means."""
        default = self.default_for()
        return self.unset if default is None and self.unset else _shown(default)

    def default_clause(self) -> str:
        """"default VALUE", or "default: what not giving it means"."""
        return f"default{':' if self.default_for() is None and self.unset else ''} {self.default_text()}"

    def help_text(self) -> str:
        """The help with the default shown (and the CloudCompare-compatible one where it differs)."""
        text = f"{self.help} ({self.default_clause()}"
        if self.cloudcompare is not SAME:
            text += f"; {_shown(self.cloudcompare)} with --compat cloudcompare"
        return text + ")"


def _shown(value) -> str:
    if value is None:
        return "none"
    if value is True or value is False:
        return "on" if value else "off"
    if isinstance(value, (list, tuple)):
        return ",".join(_shown(v) for v in value)
    return str(value)
