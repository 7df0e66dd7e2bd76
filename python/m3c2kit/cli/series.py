"""The `m3c2 series` command line (docs/series.md), registered by m3c2kit.cli.main.make_parser:

    m3c2 series REFERENCE EPOCH... -o STORE [compare options]   create a store
    m3c2 series add STORE EPOCH...                               append epochs (resumes a killed run)
    m3c2 series smooth STORE --window N                          temporal median -> smoothed_distance
    m3c2 series kalman STORE [--model M] [--process-noise Q|auto] Kalman filter and RTS smoother -> kalman_*
    m3c2 series tam3c2 STORE [--required-points N] [--window-ratio R] time-adaptive M3C2 -> tam3c2_*
    m3c2 series changepoints STORE --core I                      change points of one core point
    m3c2 series objects STORE -o OBJECTS.csv                     4D objects-by-change
    m3c2 series report STORE -o REPORT.html                      time series and object plots
    m3c2 series import ARCHIVE.zip -o STORE                      a py4dgeo analysis archive
    m3c2 series check STORE                                      is the store whole? (exit 1 naming each damage)

The first word after `series` decides the form: one of the action words, or else the reference
of a new store (a reference file literally named like an action is written ./add)."""
from __future__ import annotations

import argparse
from contextlib import contextmanager
from pathlib import Path

from .command_index import summary
from ..base.errors import UsageError
from ..io.collisions import require_suffix
from .integers import integer
from .options import add, add_table_option, step_options
from ..io.files import add_drop_nonfinite_option

ACTIONS = ("add", "smooth", "kalman", "tam3c2", "changepoints", "objects", "report", "import", "check")
STORE_HELP = "the series store (a Zarr directory)"
#: The compare parameters a series takes: the parameter table's engine parameters (their flags,
#: types, ranges and help), the core spacing and --compat; not the per-point uncertainty's inputs
#: nor the output options, which concern one pair's files.
SERIES_SCOPES = ("engine", "alias")
SERIES_RUN_PARAMETERS = ("core_spacing", "compat")
#: The largest core point index an option takes (numpy's int64 indices).
INDEX_MAX = 2**63 - 1


def _parser(prog: str, description: str):
    from .parser import ArgumentParser  # usage errors exit 2 with one line
    return ArgumentParser(prog=prog, description=description)


def series_parameters():
    from ..settings.table import parameters_of
    return [p for p in parameters_of("compare") if p.scope in SERIES_SCOPES or p.name in SERIES_RUN_PARAMETERS]


def _compare_options(p, required: bool, core_group=None) -> None:
    """The table's options (as m3c2 compare's); --projection-scale and --max-depth are required
    to create a store, optional (checked against the store's) for add."""
    g = p.add_argument_group("M3C2 parameters (those of m3c2 compare; stored in the store)")
    for param in series_parameters():
        target = core_group if param.name == "core_spacing" and core_group is not None else g
        add_table_option(target, param, compat=True,
                         required=required and param.name in ("projection_scale", "max_depth"))


def _run_options(p) -> None:
    add_table_option(p, "threads", filled=True)
    add(p, "dask_scheduler")  # the epochs as tasks; every worker reads the reference, the epochs and the store
    add_drop_nonfinite_option(p)
    add(p, "ignore_crs")
    add(p, "quiet")


def create_parser():
    p = _parser("m3c2 series", "Create a time-series store: core points and normals from REFERENCE once, then every "
                               "EPOCH compared with it (each equal to m3c2 compare REFERENCE EPOCH) and committed. "
                               f"Other forms: m3c2 series {{{','.join(ACTIONS)}}} ... (docs/series.md).")
    p.add_argument("reference", type=Path, help="reference cloud")
    p.add_argument("epochs", nargs="+", help="epoch files, globs ('scans/*.laz'), or a list file of 'PATH, TIME' lines")
    p.add_argument("-o", "--output", type=Path, required=True, help="the store (a Zarr directory)")
    core = p.add_mutually_exclusive_group()
    add(core, "core", default_text="every reference point")
    add(p, "core_normals")
    _compare_options(p, required=True, core_group=core)
    step_options(p, "series")  # the store's layout
    _run_options(p)
    return p


def add_parser():
    p = _parser("m3c2 series add", "Append epochs to a store with its stored parameters; epochs already in it are "
                                   "skipped, so rerunning a killed command resumes it.")
    p.add_argument("store", type=Path, help=STORE_HELP)
    p.add_argument("epochs", nargs="+", help="epoch files, globs or a list file of 'PATH, TIME' lines")
    _compare_options(p, required=False)
    _run_options(p)
    return p


def smooth_parser():
    p = _parser("m3c2 series smooth", "Temporal median of distance over WINDOW epochs, written to the store as "
                                      "smoothed_distance (Anders et al. 2021, 2.2), chunk by chunk.")
    p.add_argument("store", type=Path, help=STORE_HELP)
    step_options(p, "series smooth")
    add_table_option(p, "threads", filled=True)
    add(p, "quiet")
    return p


def tam3c2_parser():
    p = _parser("m3c2 series tam3c2", "Time-adaptive M3C2 (Huang et al., ISPRS Annals 2026): for each core point "
                                      "and epoch, the reference's and the epoch's cylinders each aggregate the "
                                      "epochs nearest in time until --required-points points, within a window of "
                                      "--window-ratio times the epoch's time from the reference; the epochs are "
                                      "read again from the store's recorded files. Writes tam3c2_distance, "
                                      "tam3c2_lod, tam3c2_significant, tam3c2_window, tam3c2_n1, tam3c2_n2 "
                                      "(docs/series.md, \"TAM3C2\").")
    p.add_argument("store", type=Path, help=STORE_HELP)
    step_options(p, "series tam3c2")
    add_table_option(p, "confidence")  # of tam3c2_lod; default: the store's
    add_table_option(p, "threads", filled=True)
    add(p, "quiet")
    return p


def kalman_parser():
    p = _parser("m3c2 series kalman", "Kalman filter and Rauch-Tung-Striebel smoother of each core point's distance "
                                      "series (Winiwarter et al. 2023), each epoch weighted by its LOD; writes "
                                      "kalman_distance, kalman_rate (and kalman_acceleration) with their sigmas and "
                                      "kalman_significant to the store. After m3c2 series add, a rerun filters only the "
                                      "new epochs and smooths again over all (docs/series.md).")
    p.add_argument("store", type=Path, help=STORE_HELP)
    step_options(p, "series kalman")
    add_table_option(p, "confidence")  # of kalman_significant; default: the store's
    add_table_option(p, "threads", filled=True)
    add(p, "quiet")
    return p


#: The argument groups of the objects and changepoints forms, by the rows' section.
OBJECTS_GROUPS = {"Anders et al. 2021, 2.3.1": "seeds: change points (Anders et al. 2021, 2.3.1; py4dgeo's defaults)",
                  "Anders et al. 2021, 2.3.2": "region growing (2.3.2) and filters (2.3.3)",
                  "Anders et al. 2021, 2.3.3": "region growing (2.3.2) and filters (2.3.3)"}


def _core_index_option(p, *, required: bool = False, default_text: str | None = None) -> None:
    text = "core point index (repeatable)"
    p.add_argument("--core", type=integer(0, INDEX_MAX), action="append", required=required,
                   help=text if default_text is None else f"{text} (default: {default_text})")


def objects_parser():
    p = _parser("m3c2 series objects", "4D objects-by-change (Anders et al. 2021): seeds, region growing on the "
                                       "normalised DTW with adaptive thresholds, filters. Writes OBJECTS (CSV), "
                                       "OBJECTS_members.csv and the store's `object` label per core point and epoch.")
    p.add_argument("store", type=Path, help=STORE_HELP)
    p.add_argument("-o", "--output", type=Path, required=True, help="objects table (CSV)")
    step_options(p, "series objects", OBJECTS_GROUPS)
    add_table_option(p, "threads", filled=True)
    add(p, "quiet")
    return p


def changepoints_parser():
    p = _parser("m3c2 series changepoints", "Change points of core points' series (the detection 4D-OBC's seeds use).")
    p.add_argument("store", type=Path, help=STORE_HELP)
    _core_index_option(p, required=True)
    step_options(p, "series changepoints", OBJECTS_GROUPS)
    add(p, "quiet")  # accepted as by every form; the change points are the output and still printed
    return p


def report_parser():
    p = _parser("m3c2 series report", "HTML report of a store: time series with LOD band per core point, the "
                                      "Kalman-smoothed series with its band (after m3c2 series kalman), object "
                                      "extents and their series (after m3c2 series objects).")
    p.add_argument("store", type=Path, help=STORE_HELP)
    p.add_argument("-o", "--output", type=Path, required=True, help="the report (HTML)")
    _core_index_option(p, default_text="a few")  # the core points plotted
    p.add_argument("--objects", type=Path, help="objects table of m3c2 series objects (default: none)")
    add(p, "quiet")
    return p


def import_parser():
    p = _parser("m3c2 series import", "Convert a py4dgeo SpatiotemporalAnalysis archive (.zip) into a store.")
    p.add_argument("archive", type=Path, help="a py4dgeo SpatiotemporalAnalysis archive (.zip)")
    p.add_argument("-o", "--output", type=Path, required=True, help="the store to write (a Zarr directory)")
    add(p, "quiet")
    return p


def check_parser():
    p = _parser("m3c2 series check", "Verify a store: committed root metadata, each array's shape against the "
                                     "commit, every chunk present and decoding (its checksum), no half-written "
                                     "variable. Exit 0 when sound, 1 naming each damage; reads only.")
    p.add_argument("store", type=Path, help=STORE_HELP)
    add(p, "quiet")  # only the damages are printed
    return p


PARSERS = {"add": add_parser, "smooth": smooth_parser, "kalman": kalman_parser, "tam3c2": tam3c2_parser,
           "changepoints": changepoints_parser,
           "objects": objects_parser, "report": report_parser, "import": import_parser, "check": check_parser}


def series_parsers(sub) -> None:
    """Adds `series`: its words are parsed by the form's own parser (see the module docstring)."""
    p = sub.add_parser("series", help=summary("series"),
                       add_help=False, prefix_chars="\0",
                       usage=f"m3c2 series REFERENCE EPOCH... -o STORE | m3c2 series {{{','.join(ACTIONS)}}} ...")
    p.add_argument("words", nargs=argparse.REMAINDER, help="REFERENCE EPOCH... -o STORE, or an action and its "
                                                           "arguments (m3c2 series ACTION --help)")
    p.set_defaults(run=run_series)


def _settings(args) -> dict:
    return {p.name: getattr(args, p.name) for p in series_parameters() if getattr(args, p.name, None) is not None}


def _log(args):
    return (lambda *a: None) if getattr(args, "quiet", False) else print


def run_series(outer) -> int:
    words = list(outer.words)
    if not words or words[0] in ("-h", "--help"):
        create_parser().print_help()
        print("\nother forms:\n" + "\n".join(f"  m3c2 series {a} ..." for a in ACTIONS))
        return 0 if words else 2
    action = words[0] if words[0] in ACTIONS else None
    args = PARSERS[action]().parse_args(words[1:]) if action else create_parser().parse_args(words)
    return globals()[f"_run_{action or 'create'}"](args)


def _check_outputs(outputs: dict, inputs: dict, *, store: bool = False, reads_store=None) -> None:
    """No output may be an input (m3c2kit.io.collisions), checked before any work, as for every
    command (docs/errors.md, "Output"). `store`: the outputs are stores (folders), so an existing
    folder there is not refused as a folder. `reads_store`: a store the command reads; then the
    store itself, every path inside it, its reference and its epochs' recorded sources are inputs
    too (`report -o STORE/zarr.json` destroyed the store, `-o` the reference's path overwrote it)."""
    from ..io.collisions import check_outputs
    if store:
        outputs = {k: v for k, v in outputs.items() if v is not None and not Path(v).is_dir()}
    check_outputs(outputs, inputs)  # the inputs named on the command line first: no store needs opening
    from ..series.outputs import refuse_inside_any_store
    refuse_inside_any_store(outputs)  # no output inside any series store, read by this command or not
    if reads_store is not None:
        from ..series.outputs import refuse_inside, store_inputs
        refuse_inside(outputs, Path(reads_store))
        check_outputs(outputs, store_inputs(Path(reads_store)))


def _epoch_files(epochs) -> dict:
    """The epochs given as existing file paths (globs and list files name others)."""
    return {f"epoch {e}": Path(e) for e in epochs if Path(e).is_file()}


@contextmanager
def _dask_client(args):
    """A client of --dask-scheduler (None without it), connected before anything is read or created:
    an address that never answers fails within run.dask.DASK_CONNECT_TIMEOUT, leaving no store."""
    if getattr(args, "dask_scheduler", None) is None:
        yield None
        return
    from ..run.dask import connect
    client = connect(args.dask_scheduler)
    try:
        yield client
    finally:
        client.close()


def _reading(args):
    """How the series reads and compares its clouds (series.run_options.EpochReading)."""
    from ..series.run_options import EpochReading
    return EpochReading(drop_nonfinite=args.drop_nonfinite, ignore_crs=args.ignore_crs, threads=args.threads or 0)


def _run_create(args) -> int:
    _check_outputs({"-o": args.output}, {"reference cloud": args.reference, **_epoch_files(args.epochs),
                                         "core points file": args.core, "core normals file": args.core_normals}, store=True)
    from ..series import run
    from ..series.run_options import CoreInput, DaskTarget, StoreLayout
    core = CoreInput(path=args.core, normals=args.core_normals)
    run.preflight(_settings(args), core)  # as m3c2 compare: every option checked before the Dask connection
    with _dask_client(args) as client:
        added = run.create(args.reference, args.epochs, args.output, _settings(args), core=core,
                           layout=StoreLayout(core_chunk=args.core_chunk, epoch_chunk=args.epoch_chunk),
                           reading=_reading(args), dask=DaskTarget(address=args.dask_scheduler, client=client),
                           log=_log(args))
    _log(args)(f"{args.output}: {added} epoch(s)")
    return 0


def _run_add(args) -> int:
    from ..series import run
    from ..series.run_options import DaskTarget
    with _dask_client(args) as client:
        added = run.add(args.store, args.epochs, given_settings=_settings(args), reading=_reading(args),
                        dask=DaskTarget(address=args.dask_scheduler, client=client), log=_log(args))
    _log(args)(f"{args.store}: {added} epoch(s) added")
    return 0


def _run_smooth(args) -> int:
    from ..series.analysis import smooth
    n = smooth(args.store, args.window, args.threads or 0)
    _log(args)(f"{args.store}: smoothed_distance over {n} epochs (window {args.window})")
    return 0


def _run_kalman(args) -> int:
    from ..series.kalman import KalmanOptions, kalman
    options = KalmanOptions(model=args.model, process_noise=args.process_noise, noise=args.noise,
                            confidence=args.confidence, from_scratch=args.from_scratch, threads=args.threads or 0,
                            observation=args.observation)
    out = kalman(args.store, options)
    if not args.quiet:
        how = (f"resumed after epoch {out['resumed_from'] - 1}" if out["resumed_from"]
               else "from the first epoch")
        q = f"q = {out['process_noise']:.6g} ({'maximum likelihood' if out['source'] == 'auto' else 'given'})"
        print(f"{args.store}: Kalman {args.model} model ({args.observation} observation) over {out['epochs']} epochs, "
              f"{how}, {q}"
              f"{'; ' + out['note'] if out['note'] else ''}; significant at {out['confidence']:g}")
    return 0



def _run_tam3c2(args) -> int:
    from ..series.tam3c2 import Tam3c2Options, tam3c2
    options = Tam3c2Options(normal_radii=None if args.normal_radius is None else tuple(args.normal_radius),
                            window_ratios=tuple(args.window_ratio), min_points=args.required_points, weights=args.weights,
                            sigma_ratio=args.sigma_ratio, space_time_ratio=args.space_time_ratio,
                            reference_time=args.reference_time, confidence=args.confidence, lod=args.tam3c2_lod,
                            fallback=args.fallback, breaks=args.window_breaks, break_width=args.break_width,
                            break_min_size=args.break_min_size, break_penalty=args.break_penalty,
                            threads=args.threads or 0)
    out = tam3c2(args.store, options)
    if not args.quiet:
        print(f"{args.store}: TAM3C2 over {out['epochs']} epochs, {out['computed']} of {out['cells']} distances "
              f"computed ({out['from_epoch']} the epoch's own M3C2); LOD ({out['lod']}) at {out['confidence']:g}")
    return 0

def check_objects_options(args) -> None:
    """The objects options that contradict each other, refused before the store is opened."""
    if getattr(args, "max_segments", 0) and args.max_segments < args.min_segments:
        raise UsageError(f"--max-segments {args.max_segments} is below --min-segments {args.min_segments}: no object "
                         f"could be kept")
    if args.window_min_size > args.window_width:
        raise UsageError(f"--window-min-size {args.window_min_size} exceeds --window-width {args.window_width}: no "
                         f"change point fits the window")


def objects_params(args):
    """The engine's ObjectsParams from the objects form's rows (settings/series_rows.py)."""
    from ..series import engine
    from ..settings.series_rows import engine_fields
    check_objects_options(args)
    return engine.objects_params(**engine_fields("series objects", "ObjectsParams", vars(args)))


def _run_objects(args) -> int:
    from ..series.outputs import members_path
    check_objects_options(args)
    _check_outputs({"-o": args.output, "-o's members table": members_path(args.output)}, {"store": args.store},
                   reads_store=args.store)
    require_suffix("-o", args.output, (".csv",), "the objects table")  # its content is CSV
    from ..series.analysis import objects
    out = objects(args.store, args.output, objects_params(args), use=args.use, threads=args.threads or 0)
    if not args.quiet:
        print(f"{args.output}: {len(out['object_seed'])} object(s) from {len(out['seed_core'])} seed(s) "
              f"on {out['variable']}; labels in {args.store} (variable object)")
    return 0


def _run_check(args) -> int:
    from ..base.errors import printable
    from ..series.integrity import check
    from ..series.store import StoreError
    if not args.store.exists():  # "damaged ... 1 damage(s)" for a path that is not there
        raise StoreError(f"{args.store}: no such store (no file or folder of that name)")
    found, damages = check(args.store)
    for line in found:
        _log(args)(printable(f"{args.store}: {line}"))
    for line in damages:
        print(printable(f"{args.store}: damaged: {line}"))
    if damages:
        raise StoreError(f"{args.store}: {len(damages)} damage(s) found, the first: {damages[0]}")
    _log(args)(printable(f"{args.store}: sound"))
    return 0


def _run_changepoints(args) -> int:
    import numpy as np
    from ..series import engine
    from ..series.analysis import series_of
    for c in args.core:
        ts, name = series_of(args.store, c, args.use)
        good = ~np.isnan(ts)
        if good.sum() < 3:
            print(f"core {c}: fewer than 3 epochs with a distance")
            continue
        ts = np.interp(np.arange(len(ts)), np.flatnonzero(good), ts[good])
        cps = engine.change_points(ts, args.window_width, args.window_min_size, args.window_jump, args.window_penalty)
        print(f"core {c} ({name}): change points at epochs {', '.join(map(str, cps)) or 'none'}")
    return 0


def _run_report(args) -> int:
    from ..series.outputs import members_path
    from ..series.report import write_report
    tables = {"objects table": args.objects,
              "objects' members table": members_path(args.objects) if args.objects is not None else None}
    _check_outputs({"-o": args.output}, {"store": args.store, **tables}, reads_store=args.store)
    require_suffix("-o", args.output, (".html", ".htm"), "the report")  # its content is HTML
    from ..series.integrity import require_present
    require_present(args.store)  # a damaged store is refused, not drawn from fill values
    write_report(args.store, args.output, cores=args.core, objects_table=args.objects)
    _log(args)(f"wrote {args.output}")
    return 0


def _run_import(args) -> int:
    _check_outputs({"-o": args.output}, {"archive": args.archive}, store=True)
    from ..series.py4dgeo_archive import import_archive
    n = import_archive(args.archive, args.output)
    _log(args)(f"{args.output}: {n} epoch(s) imported from {args.archive}")
    return 0
