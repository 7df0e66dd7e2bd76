"""The plan of a compare run, shared by every way of executing it (in memory, tiled, on Dask):
the keywords as given (the record a Result keeps), their resolved values (m3c2kit.settings), the
engine's Params, the per-point inputs each cloud carries (--uncertainty pm / ep) and the
vegetation filter (--classifier / --keep). Each executor starts from :func:`make_plan`, so the
checks of the options, and their messages, are the same in every mode."""
from __future__ import annotations

from dataclasses import dataclass, field

from .. import uncertainty_inputs
from ..errors import UsageError
from ..settings import engine_params, orientation, resolve


@dataclass
class Filter:
    """--classifier FILE --keep CLASS: both clouds reduced to the points classified as a kept
    class (section 4.3, CANUPO; m3c2kit.classify) before the comparison."""

    path: object
    classifier: object
    keep: list


@dataclass
class Plan:
    given: dict
    values: dict
    engine: object  # engine Params
    carried: dict = field(default_factory=dict)  # cloud name -> [uncertainty_inputs.Carried]
    filter: Filter | None = None

    @property
    def record(self) -> dict:
        """The parameters a Result records (its report shows them): those given, with D as a list."""
        return run_record(self.given, self.engine)


def run_record(given: dict, engine_p) -> dict:
    return dict({k: v for k, v in given.items() if k != "threads"}, normal_scale=list(engine_p.normal_diameters))


def make_plan(params: dict, read_points=None, *, core_points=orientation.LATER, scan_positions=None) -> Plan:
    """The plan of compare(**params) (the parameter table's keywords, m3c2kit.settings.table).
    `core_points` and `scan_positions`: what --orient barycentre and sensor read (settings.
    engine_params); the executor that knows them later sets the plan's engine Params again."""
    values = resolve(params, "compare", api=True)
    engine_p = engine_params(values, "compare", read_points, core_points=core_points, scan_positions=scan_positions)
    return Plan(given=dict(params), values=values, engine=engine_p, carried=uncertainty_inputs.carried(values),
                filter=_filter(values))


def _filter(values: dict) -> Filter | None:
    if (values["classifier"] is None) != (values["keep"] is None):
        raise UsageError("--classifier and --keep go together: the classifier's classes to keep, e.g. "
                         "--classifier veg.json --keep ground")
    if values["classifier"] is None:
        return None
    from ..classify import read_classifier
    keep = [k.strip() for k in str(values["keep"]).split(",") if k.strip()]
    clf = read_classifier(values["classifier"])
    unknown = [k for k in keep if k not in clf.labels]
    if unknown:
        raise UsageError(f"--keep {','.join(unknown)}: not a class of the classifier (its classes: "
                         f"{', '.join(clf.labels)})")
    return Filter(values["classifier"], clf, keep)
