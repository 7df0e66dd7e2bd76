"""The compare parameters of a series: checked as `m3c2 compare` checks them (the parameter
table's resolve, so an option gives the same message in both), recorded in the store, and made
into the engine's Params by the compare run's plan (run.plan.make_plan).

What the store records (its ``parameters`` attribute, JSON) is what a later ``add``, and every
Dask worker, needs to rebuild the same Params without the files create read: the options given,
with ``--orient`` resolved where it depends on those files (section 3.1.2: the orientation fixes
the sign of every distance, so it may not drift between epochs):

* not given: the one default rule (settings.orientation.for_clouds: towards the scan positions of
  the cloud the core points come from, else the reference's, else +z), recorded as the points
  (a list of [x, y, z]) or ``"+z"`` -- as stores of format 1 and 2 have always recorded it;
* ``sensor`` and a FILE of points: the points read, ``{"away": points}`` for ``away:``;
* anything else (an axis, X,Y,Z, origin, barycentre of the stored core points): as given.

``--error-model`` is recorded as the model's content (its JSON document), not the file's path.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from ..base.errors import UsageError
from ..run.plan import make_plan
from ..settings import error_model, orientation, resolve
from . import store as st

#: The recorded form of an orientation away from points (a list of points is towards them).
AWAY_KEY = "away"


def checked(settings: dict) -> dict:
    """The resolved values of a new series' settings, or the UsageError m3c2 compare gives for
    the same options (values, ranges, the rules that tie parameters, options that act nowhere)."""
    return resolve(settings, "compare", api=True)


def check_against_store(store, stored: dict, given: dict) -> None:
    """`add`: the options given are checked as compare checks them (with the store's for the
    others), then each must equal the store's: a store holds one parameter set. ``--orient``
    is compared once the files it may depend on are read (:func:`check_orient`)."""
    resolve(dict(_keywords(stored), **given), "compare", api=True, check_needs=False)
    for name, value in given.items():
        if name == "error_model":  # the store records the model's content: the file's is compared
            value = recorded_error_model(value)
        if name not in ("threads", "orient") and st.canonical(stored.get(name)) != st.canonical(value):
            raise _other_parameters(store, name, stored.get(name), value)


def check_orient(store, stored: dict, given, recorded_given) -> None:
    """`add --orient`: the store's orientation and the one given, resolved as create records it
    (`recorded_given`, :func:`recorded_orient`)."""
    if given is not None and st.canonical(stored.get("orient")) != st.canonical(recorded_given):
        raise _other_parameters(store, "orient", stored.get("orient"), given)


def _other_parameters(store, name: str, stored, given) -> UsageError:
    return UsageError(f"{store} was computed with {name} = {stored!r}, not {given!r}: a store holds epochs of one "
                      f"parameter set; create a new store for other parameters")


def recorded_orient(spec, reference, core_cloud=None, *, reference_name: str, core_name: str | None = None,
                    read_points: Callable | None = None):
    """The JSON value a store records for `spec` (the module docstring), with the scan positions
    of `reference` and `core_cloud` (m3c2kit.io.Cloud) and a FILE read by `read_points`."""
    resolved = orientation.for_clouds(spec, reference, core_cloud, reference_name=reference_name,
                                      core_name=core_name, origin=f"--orient {spec}")
    if _reads_file(resolved):
        _, points, away = orientation.orientation(resolved, read_points)
        resolved = orientation.PointOrientation(points, away)
    if isinstance(resolved, orientation.PointOrientation):
        points = np.asarray(resolved.points, dtype=np.float64).reshape(-1, 3).tolist()
        return {AWAY_KEY: points} if resolved.away else points
    return resolved


def recorded(settings: dict, reference, core_cloud=None, *, reference_name: str, core_name: str | None = None,
             read_points: Callable | None = None) -> dict:
    """`settings` as the store records them: with --orient resolved (none with --normal-source
    core, whose given normals are used as they are: settings.needs), and --error-model's model
    by its content (:func:`recorded_error_model`)."""
    if settings.get("error_model") is not None:
        settings = dict(settings, error_model=recorded_error_model(settings["error_model"]))
    if settings.get("normal_source") == "core":
        return dict(settings)
    orient = recorded_orient(settings.get("orient"), reference, core_cloud, reference_name=reference_name,
                             core_name=core_name, read_points=read_points)
    return dict(settings, orient=orient)


def recorded_error_model(value):
    """--error-model as a store records it: the model's CONTENT (its JSON document), not the file's
    path, so that ``add`` computes the same LOD when the file has moved or changed (a store holds
    one parameter set); a content already recorded stays as it is."""
    return None if value is None else error_model.for_compare(value).to_json()


def engine_params(recorded_settings: dict, core: np.ndarray):
    """The engine's Params of recorded settings for the store's core points (the barycentre of
    --orient barycentre is theirs), through the compare run's plan."""
    return make_plan(_keywords(recorded_settings), core_points=core).engine


def _keywords(recorded_settings: dict) -> dict:
    """The parameter table's keywords of recorded settings: recorded points become the
    orientation they stand for (settings.orientation.PointOrientation)."""
    orient = recorded_settings.get("orient")
    if isinstance(orient, list):
        return dict(recorded_settings, orient=orientation.PointOrientation(_points(orient)))
    if isinstance(orient, dict) and set(orient) == {AWAY_KEY}:
        return dict(recorded_settings, orient=orientation.PointOrientation(_points(orient[AWAY_KEY]), away=True))
    return dict(recorded_settings)


def _points(values) -> np.ndarray:
    return np.asarray(values, dtype=np.float64).reshape(-1, 3)


def _reads_file(spec) -> bool:
    """Whether the orientation rule (settings.orientation.orientation) reads `spec` as a FILE of
    points: asked of the rule itself, so no second parser of --orient's values exists."""
    asked = []

    def probe(path):
        asked.append(path)
        return np.zeros((1, 3))

    try:
        orientation.orientation(spec, probe, core_points=orientation.LATER, scan_positions=np.zeros((1, 3)))
    except UsageError:
        return False  # no valid value: the plan says why, as compare's does
    return bool(asked)
