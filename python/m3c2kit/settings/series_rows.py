"""The parameter table's rows of the series steps (`m3c2 series smooth|kalman|tam3c2|objects|
changepoints` and the store's layout; docs/series.md): each option once, with its flag, range,
help and default. A default the step's engine struct holds (ObjectsParams, Tam3c2Params,
KalmanParams: include/m3c2/objects_by_change.hpp, tam3c2.hpp, kalman.hpp) is read from it, as
compare's are from Params; the others are the row's. The command line's series parsers, the
Python options' defaults (series/kalman.py, series/tam3c2.py) and QGIS's series algorithms
(through parameters.json) are built from these rows (issue 41: a hand-written QGIS copy had
drifted)."""
from __future__ import annotations

from .. import engine
from .needs import Needs
from .parsers import AutoOr, Choice, Flag, Integer, Numbers, Real, Text, UINT32_MAX
from .row import FROM_ENGINE, EngineField, Parameter, enum, same

__all__ = ["SERIES_ROWS", "KALMAN_ORDERS", "OBJECTS_SERIES", "row", "engine_fields"]

OBJECTS = "series objects"
CHANGEPOINTS = "series changepoints"
SEEDS = (OBJECTS, CHANGEPOINTS)  # the change-point detection 4D-OBC's seeds use, and the series read
KALMAN = "series kalman"
TAM3C2 = "series tam3c2"
#: The Kalman state's names and their sizes (KalmanParams.order).
KALMAN_ORDERS = {"velocity": 2, "acceleration": 3}
#: The series 4D-OBC and the change points read: smoothed_distance when present, distance, or
#: the Kalman filter's kalman_distance (series/analysis.py, analysed_variable).
OBJECTS_SERIES = ("auto", "smoothed", "raw", "kalman")

COUNT = Integer(1, UINT32_MAX, "an integer >= 1")
COUNT_OR_ZERO = Integer(0, UINT32_MAX, "an integer >= 0")
WINDOW = Integer(2, UINT32_MAX, "an integer >= 2")

OBJECTS_PARAMS = "ObjectsParams"
TAM3C2_PARAMS = "Tam3c2Params"
KALMAN_PARAMS = "KalmanParams"


def _objects(field: str) -> EngineField:
    return same(field, OBJECTS_PARAMS)


def _tam3c2(field: str) -> EngineField:
    return same(field, TAM3C2_PARAMS)


FINISHED_ONLY = EngineField(("use_unfinished",), lambda v, **_: {"use_unfinished": not v},
                            lambda f: not f["use_unfinished"], OBJECTS_PARAMS)
KALMAN_ORDER = EngineField(("order",), lambda v, **_: {"order": KALMAN_ORDERS[v]},
                           lambda f: {k: name for name, k in KALMAN_ORDERS.items()}[f["order"]], KALMAN_PARAMS)
KALMAN_NOISE = EngineField(("discrete_noise",), lambda v, **_: {"discrete_noise": v == "discrete"},
                           lambda f: "discrete" if f["discrete_noise"] else "continuous", KALMAN_PARAMS)

GAUSSIAN = Needs(lambda v: v.get("weights") == "gaussian", "with --weights gaussian")
WEIGHTED = Needs(lambda v: v.get("weights") not in (None, "none"), "with --weights linear or gaussian")
BREAKS = Needs(lambda v: v.get("window_breaks") == "changepoints", "with --window-breaks changepoints")


def _row(name, flag, kind, help, section, commands, *, engine_field=None, default=None, **more):
    """A series row; `default`: the row's own (None: not given) where no engine field holds it;
    `more`: Parameter's other fields (cli_type, str unless given; metavar, needs, unset, label)."""
    more.setdefault("cli_type", str)
    return Parameter(name, flag, kind, help, section, engine=engine_field,
                     default=FROM_ENGINE if engine_field is not None and default is None else default,
                     commands=tuple(commands), scope="series", **more)


SERIES_ROWS: tuple[Parameter, ...] = (
    # The store's layout (m3c2 series REFERENCE EPOCH... -o STORE)
    _row("core_chunk", "--core-chunk", COUNT, "core points per chunk of the store", "docs/series.md", ("series",),
         default=16384),
    _row("epoch_chunk", "--epoch-chunk", COUNT, "epochs per chunk of the store", "docs/series.md", ("series",),
         default=8),
    # m3c2 series smooth (Anders et al. 2021, 2.2)
    _row("window", "--window", COUNT, "epochs in the temporal median's window, centred", "Anders et al. 2021, 2.2",
         ("series smooth",), default=24),
    # m3c2 series kalman (Winiwarter et al. 2023; docs/series.md, "Kalman filter")
    _row("model", "--model", Choice(*KALMAN_ORDERS), "the state: distance and rate (velocity), or also the "
         "acceleration", "Winiwarter et al. 2023", (KALMAN,), engine_field=KALMAN_ORDER),
    _row("process_noise", "--process-noise", AutoOr(Real(closed=True)),
         "q of the process noise Q = q M(dt), in the distances' unit and days; auto: the q of maximum likelihood",
         "Winiwarter et al. 2023", (KALMAN,), default="auto", metavar="Q|auto"),
    _row("noise", "--noise", Choice("continuous", "discrete"),
         "continuous white noise on the highest derivative, or the piecewise-constant (discrete) noise of kalman4d "
         "and filterpy", "docs/series.md", (KALMAN,), engine_field=KALMAN_NOISE),
    _row("observation", "--observation", Choice("shared", "independent"),
         "shared: the state holds the reference cylinder's error, which every epoch's distance shares, and each "
         "core point's scatter pooled over its epochs weighs every epoch with a distance (calibrated bands); "
         "independent: each epoch's LOD as independent noise, the model of kalman4d and the tum-rsa fork, "
         "over-confident where the reference is no denser than the epochs", "docs/series.md", (KALMAN,),
         engine_field=same("observation", KALMAN_PARAMS)),
    _row("from_scratch", "--from-scratch", Flag(), "filter every epoch again (and estimate q again with auto) "
         "instead of resuming", "docs/series.md", (KALMAN,), default=False, cli_type=None),
    # m3c2 series tam3c2 (Huang et al., ISPRS Annals 2026; docs/series.md, "TAM3C2")
    _row("required_points", "--required-points", COUNT, "aggregation stops when a side holds this many points "
         "(the reference's required_points)", "Huang et al. 2026", (TAM3C2,), engine_field=_tam3c2("min_points")),
    _row("window_ratio", "--window-ratio", Numbers(at_most=1.0), "the window's half-width over |t_epoch - "
         "t_reference|; several: chosen per core point with the normal radius (the reference's max_window_ratio)",
         "Huang et al. 2026", (TAM3C2,), default=(0.2,), metavar="R[,R...]"),
    _row("normal_radius", "--normal-radius", Numbers(), "radii of the normal's sphere; several: chosen per core "
         "point", "Huang et al. 2026", (TAM3C2,), metavar="R[,R...]", unset="the store's normal scales / 2"),
    _row("weights", "--weights", Choice(*engine.TAM3C2_CHOICES["weights"]), "space-time weights of the points, with "
         "Kish's effective n in the LOD", "Huang et al. 2026", (TAM3C2,), engine_field=_tam3c2("weights")),
    _row("sigma_ratio", "--sigma-ratio", Real(), "with --weights gaussian: their width in units of the radius and window",
         "Huang et al. 2026", (TAM3C2,), engine_field=_tam3c2("sigma_ratio"), needs=(GAUSSIAN,)),
    _row("space_time_ratio", "--space-time-ratio", Real(), "with --weights linear or gaussian: the temporal kernel's "
         "window is the window times this",
         "Huang et al. 2026", (TAM3C2,), engine_field=_tam3c2("space_time_ratio"), needs=(WEIGHTED,)),
    _row("reference_time", "--reference-time", Text("a time (ISO 8601)"), "the reference's time when the store "
         "has none recorded", "Huang et al. 2026", (TAM3C2,), metavar="TIME", unset="the store's"),
    _row("fallback", "--fallback", Choice(*engine.TAM3C2_CHOICES["fallback"]), "a cell whose windows leave a side "
         "short of --required-points: the epoch's own M3C2 from the store where it has a distance (m3c2; "
         "tam3c2_window 0) or the authors' rule (none)", "docs/series.md", (TAM3C2,),
         engine_field=_tam3c2("fallback"), default="m3c2"),  # ours; the engine's is the authors' rule
    _row("window_breaks", "--window-breaks", Choice(*engine.TAM3C2_CHOICES["breaks"]), "changepoints: the windows "
         "stop at the change points of the core point's per-epoch M3C2 distances, so that none borrows across a "
         "step (none: the authors' rule)", "docs/series.md", (TAM3C2,), engine_field=_tam3c2("breaks")),
    _row("break_width", "--break-width", WINDOW, "epochs in the breaks' change-point window", "docs/series.md",
         (TAM3C2,), engine_field=_tam3c2("break_width"), needs=(BREAKS,), metavar="N"),
    _row("break_min_size", "--break-min-size", COUNT, "fewest epochs of a segment between breaks", "docs/series.md",
         (TAM3C2,), engine_field=_tam3c2("break_min_size"), needs=(BREAKS,), metavar="N"),
    _row("break_penalty", "--break-penalty", Real(), "a break is kept when it lowers the series' L1 cost by more "
         "than this, in the distance's unit", "docs/series.md", (TAM3C2,), engine_field=_tam3c2("break_penalty"),
         needs=(BREAKS,), metavar="P"),
    # compare's --lod offers the bootstrap, which TAM3C2 cannot resample (issue 42): its own choices
    _row("tam3c2_lod", "--lod", Choice(*engine.TAM3C2_CHOICES["lod"]), "the LOD's statistic: z, Welch's t, or "
         "auto (t when a side has under 30 points); TAM3C2 has no bootstrap", "docs/series.md", (TAM3C2,),
         unset="the store's"),
    # 4D objects-by-change: seeds from change points (Anders et al. 2021, 2.3.1; py4dgeo's defaults)
    _row("window_width", "--window-width", WINDOW, "sliding window of the change-point detection",
         "Anders et al. 2021, 2.3.1", SEEDS, engine_field=_objects("window_width"), label='Change-point window'),
    _row("window_min_size", "--window-min-size", COUNT_OR_ZERO, "fewest epochs between two change points",
         "Anders et al. 2021, 2.3.1", SEEDS, engine_field=_objects("window_min_size"), label='Fewest epochs between change points'),
    _row("window_jump", "--window-jump", COUNT, "epochs between the change-point candidates",
         "Anders et al. 2021, 2.3.1", SEEDS, engine_field=_objects("window_jump"), label='Change-point step'),
    _row("window_penalty", "--window-penalty", Real(), "least cost decrease of a change point",
         "Anders et al. 2021, 2.3.1", SEEDS, engine_field=_objects("window_penalty"), label='Change-point penalty'),
    _row("min_period", "--min-period", COUNT, "fewest epochs of a seed's change", "Anders et al. 2021, 2.3.1",
         (OBJECTS,), engine_field=_objects("min_period"), label='Fewest epochs of a change'),
    _row("height_threshold", "--height-threshold", Real(closed=True), "least magnitude of a seed's change, a change "
         "still going on at the last epoch's too (--dtw py4dgeo: not that one's, as py4dgeo)",
         "Anders et al. 2021, 2.3.1", (OBJECTS,), engine_field=_objects("height_threshold"), label='Least change of a seed'),
    _row("finished_only", "--finished-only", Flag(), "drop seeds still growing at the last epoch",
         "Anders et al. 2021, 2.3.1", (OBJECTS,), engine_field=FINISHED_ONLY, cli_type=None, label='Finished changes only'),
    _row("seed_subsampling", "--seed-subsampling", COUNT, "search every k-th core point for seeds",
         "Anders et al. 2021, 2.3.1", (OBJECTS,), engine_field=_objects("seed_subsampling"), label='Every k-th core point as a seed'),
    _row("use", "--use", Choice(*OBJECTS_SERIES), "the series: smoothed_distance when present (auto), distance "
         "(raw), or kalman_distance (after m3c2 series kalman)", "docs/series.md", SEEDS, default="auto", label='Series analysed'),
    # 4D objects-by-change: region growing (2.3.2) and filters (2.3.3)
    _row("neighbourhood_radius", "--neighbourhood-radius", Real(), "core points this close are adjacent",
         "Anders et al. 2021, 2.3.2", (OBJECTS,), engine_field=_objects("neighbourhood_radius"), label='Neighbourhood radius'),
    _row("thresholds", "--thresholds", Numbers(at_most=1.0), "DTW thresholds to choose from",
         "Anders et al. 2021, 2.3.2", (OBJECTS,), engine_field=_objects("thresholds"), label='DTW thresholds'),
    _row("min_segments", "--min-segments", COUNT_OR_ZERO, "fewest core points of an object",
         "Anders et al. 2021, 2.3.3", (OBJECTS,), engine_field=_objects("min_segments"), label='Fewest core points of an object'),
    _row("max_segments", "--max-segments", COUNT_OR_ZERO, "the choice of the DTW threshold stops at the first whose "
         "object reaches this many core points (0: no limit; at least --min-segments)", "Anders et al. 2021, 2.3.3",
         (OBJECTS,), engine_field=_objects("max_segments"), label='Most core points of an object'),
    _row("max_cv", "--max-cv", Real(), "largest coefficient of variation of an object's DTW",
         "Anders et al. 2021, 2.3.3", (OBJECTS,), engine_field=_objects("max_cv"), label='Largest coefficient of variation'),
    _row("dtw", "--dtw", Choice("baseline", "seed-start", "py4dgeo"), "seeds and DTW alignment: baseline (each "
         "series from its median before the change), seed-start (from its value at the seed's first epoch), py4dgeo "
         "(py4dgeo 1.2.0's rule: from the series' first epoch, D_max of the raw seed slice; docs/series.md, "
         "Analysis)", "Anders et al. 2021, 2.3.2", (OBJECTS,), engine_field=enum("dtw", OBJECTS_PARAMS), label='DTW alignment'),
)


def engine_fields(command: str, struct: str, values: dict) -> dict:
    """The fields of the engine struct `struct` that `command`'s rows set from `values` (by row
    name; a row absent or None keeps the struct's default)."""
    out = {}
    for row in SERIES_ROWS:
        if command in row.commands and row.engine is not None and row.engine.struct == struct \
                and values.get(row.name) is not None:
            out.update(row.engine.to_engine(values[row.name]))
    return out


def row(name: str) -> Parameter:
    """The series row `name` (settings.table.by_name holds every row; this module is imported by it)."""
    return next(r for r in SERIES_ROWS if r.name == name)
