"""The parameter table's rows of `m3c2 register` (point-to-plane ICP on stable areas;
docs/registration.md): each option of the ICP and of --auto-stable once, with its flag, range,
help and default. A default the engine's RegistrationParams holds (include/m3c2/registration.hpp)
is read from it; the others are the row's. The command line's parser (cli/register.py) and
m3c2kit.register's options (analysis/registration.py, RegistrationOptions) are built from these
rows; D (--normal-scale), --stable, --auto-stable, --ignore-crs, the threads and -q are the options
other commands share (cli/options.py)."""
from __future__ import annotations

from .. import engine
from .needs import Needs
from .parsers import Integer, Real
from .row import FROM_ENGINE, Parameter, same

__all__ = ["REGISTER", "REGISTRATION_ROWS", "AUTO_STABLE"]

REGISTER = "register"
STRUCT = "RegistrationParams"
SECTION = "docs/registration.md"
_OWN = object()  # a row whose default is the engine field's

#: --rounds counts --auto-stable's rounds.
AUTO_STABLE = Needs(lambda v: bool(v.get("auto_stable")), "with --auto-stable (it counts its register-compare rounds)")


def _row(name, flag, kind, help, label, *, field=None, default=_OWN, **more):
    """A register row; `field`: the RegistrationParams field it sets, whose default is the row's
    default unless `default` (the row's own; None: not given) is given; `more`: Parameter's other
    fields (cli_type float unless given)."""
    engine_field = same(field, STRUCT) if field is not None else None
    if default is _OWN:
        default = FROM_ENGINE if engine_field is not None else None
    return Parameter(name, flag, kind, help, SECTION, engine=engine_field, default=default, commands=(REGISTER,),
                     scope="step", label=label, **more)


REGISTRATION_ROWS: tuple[Parameter, ...] = (
    # The pairs (docs/registration.md, "The method", 3 and 4). Not given, the farthest pair is D
    # (m3c2kit.register passes it; the engine's 0 is no distance).
    _row("max_distance", "--max-distance", Real(), "the farthest pair of points ICP pairs; the clouds must be "
         "aligned to within it to start with", "Farthest pair (max distance)", field="max_distance", default=None,
         metavar="DIST", unset="D, the normal scale"),
    _row("reject", "--reject", Real(closed=True), "drop the pairs whose residual is more than K robust standard "
         "deviations (1.4826 MAD) from the residuals' median, 0 for none", "Residual rejection (robust sd)",
         field="reject", metavar="K"),
    # The iterations (5)
    _row("max_iterations", "--max-iterations", Integer(1, 1000, "an integer >= 1"), "the most ICP steps",
         "Most ICP steps", field="max_iterations", cli_type=int),
    _row("max_points", "--max-points", Integer(100, engine.COUNT_MAX, "an integer >= 100"), "at most this many "
         "compared points are paired, at a fixed stride", "Most compared points paired", field="max_points",
         cli_type=int),
    # --auto-stable's rounds
    _row("rounds", "--rounds", Integer(1, 20, "an integer >= 1"), "--auto-stable: the most register-compare rounds",
         "Most rounds (auto stable)", default=5, cli_type=int, needs=(AUTO_STABLE,)),
)
