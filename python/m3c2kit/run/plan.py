"""The plan of a compare run, shared by every way of executing it (in memory, tiled, on Dask):
the keywords as given (the record a Result keeps), their resolved values (m3c2kit.settings), the
engine's Params, the per-point inputs each cloud carries (--uncertainty pm / ep) and the
vegetation filter (--classifier / --keep), which the caller builds (m3c2kit.classify.vegetation)
and the executor takes as an input. Each executor starts from :func:`make_plan`, so the checks of
the options, and their messages, are the same in every mode."""
from __future__ import annotations

from dataclasses import dataclass, field

from . import uncertainty_inputs
from ..base.errors import UsageError
from ..settings import engine_params, orientation, resolve


@dataclass
class Plan:
    given: dict
    values: dict
    engine: object  # engine Params
    carried: dict = field(default_factory=dict)  # cloud name -> [uncertainty_inputs.Carried]
    #: --classifier / --keep: an object with ``reach``, ``filtered(cloud, name, threads)`` and
    #: ``keep_mask(near, own, threads)`` (m3c2kit.classify.vegetation.VegetationFilter), or None.
    filter: object = None

    @property
    def record(self) -> dict:
        """The parameters a Result records (its report shows them): those given, with D as a list."""
        return run_record(self.given, self.engine)


def run_record(given: dict, engine_p) -> dict:
    """The parameters a Result records: those given (the default orientation as the one in
    effect: towards the sensor when it had scan positions, else +z), with D as a list."""
    record = dict({k: v for k, v in given.items() if k != "threads"}, normal_scale=list(engine_p.normal_diameters))
    if record.get("orient") is None and record.get("normal_source") != "core":
        record["orient"] = "sensor" if len(engine_p.orientation_points) else "+z"
    return record


def make_plan(params: dict, read_points=None, *, vegetation=None, core_points=orientation.LATER,
              scan_positions=None) -> Plan:
    """The plan of compare(**params) (the parameter table's keywords, m3c2kit.settings.table).
    `vegetation`: the filter --classifier and --keep ask for, built by the caller. `core_points`
    and `scan_positions`: what --orient barycentre and sensor read (settings.engine_params); the
    executor that knows them later sets the plan's engine Params again."""
    values = resolve(params, "compare", api=True)
    if (values["classifier"] is not None) != (vegetation is not None):
        raise UsageError("--classifier and --keep need the filter they describe: run them through m3c2kit.compare "
                         "or m3c2 compare (m3c2kit.classify.vegetation.vegetation_filter builds it)")
    engine_p = engine_params(values, "compare", read_points, core_points=core_points, scan_positions=scan_positions)
    return Plan(given=dict(params), values=values, engine=engine_p, carried=uncertainty_inputs.carried(values),
                filter=vegetation)

