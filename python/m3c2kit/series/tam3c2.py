"""`m3c2 series tam3c2`: time-adaptive M3C2 over a store's epochs (docs/series.md, "TAM3C2";
Huang, Letard, Lague, Hoefle, Tabernig, Leroy & Anders, ISPRS Annals 2026), the engine's
(include/m3c2/tam3c2.hpp). The epochs are read again from the files the store recorded (the
reference, attribute `reference`; each epoch's `source`), each checked against its recorded
SHA-256, read once and cropped to each block of core points' reach (series/epoch_crops.py): a
block's pool is the reference at its time and every epoch at its own. For each core point and
epoch, the distance between the reference's side and the epoch's side, each aggregated over the epochs nearest in time to it until `--required-points`
points, within W = |t_epoch - t_reference| x ratio. Our extensions (the engine's rules, issue 41):
`--fallback m3c2` (the default) gives a cell whose windows fall short the epoch's own M3C2 from the
store; `--window-breaks changepoints` stops the windows at the change points of the core point's
per-epoch M3C2 series.

The step writes tam3c2_distance, tam3c2_lod, tam3c2_significant, tam3c2_window (epochs
aggregated, both sides together; 0: the epoch's own M3C2; -1: no distance), tam3c2_n1, tam3c2_n2
(counts, or Kish's effective n when weighted) in the staging folder, one block of core points at a time, and publishes them together
(view.publish_many): a kill leaves the previous variables, or all of them marked
half-written, never a mix."""
from __future__ import annotations

import math
import warnings
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..base import fault_hook
from ..base.errors import M3C2Error, M3C2Warning, UsageError
from .. import engine as facade
from ..io import read_cloud
from ..io.private import private_folder
from ..run.checks import threads_count
from ..settings.needs import check_effective
from ..settings.series_rows import row
from ..settings.table import parameters_of
from . import epoch_files
from .epoch_crops import EpochCrops
from .epochs import microseconds
from . import store as st
from .view import StoreView, writing

DISTANCE, LOD, SIGNIFICANT, WINDOW, N1, N2 = st.TAM3C2_VARIABLES
CHOICES = facade.TAM3C2_CHOICES  # weights, lod, fallback, breaks: the engine's names
WEIGHTS, LODS = CHOICES["weights"], CHOICES["lod"]
FROM_EPOCH = st.TAM3C2_FROM_EPOCH
#: Bytes of a block's per-(core, epoch) results and epochs' own M3C2 (17 arrays of 8 bytes): memory
#: is bounded by one block of core points: those and its pool (the epochs' points within its reach).
BLOCK_BYTES = 256 << 20


@dataclass(frozen=True)
class Tam3c2Options:
    """`m3c2 series tam3c2`'s options; their defaults the parameter table's (settings/series_rows.py)."""
    normal_radii: tuple | None = None  # the store's normal diameters / 2 when None
    window_ratios: tuple = tuple(row("window_ratio").default_for())  # the reference's example; each in (0, 1]
    min_points: int = row("required_points").default_for()  # the reference's required_points default
    weights: str = row("weights").default_for()
    sigma_ratio: float | None = None  # with gaussian weights; the engine's default when None
    space_time_ratio: float | None = None  # with weights; the engine's default when None
    reference_time: str | None = None  # the store's when None
    confidence: float | None = None  # the store's when None
    lod: str | None = None  # the LOD's statistic, z, t or auto (tam3c2.hpp, Tam3c2Lod); the store's when None
    fallback: str = row("fallback").default_for()  # a short cell: the epoch's own M3C2 (m3c2) or the authors' rule
    breaks: str = row("window_breaks").default_for()  # windows stop at change points, or not (none, the authors')
    break_width: int | None = None  # the breaks' change-point detection; the engine's default when None
    break_min_size: int | None = None
    break_penalty: float | None = None
    threads: int = 0


def _check(o: Tam3c2Options) -> None:
    if o.weights not in WEIGHTS:
        raise UsageError(f"--weights must be one of {', '.join(WEIGHTS)}, got {o.weights!r}")
    if not o.window_ratios or not all(0.0 < r <= 1.0 for r in o.window_ratios):
        raise UsageError(f"--window-ratio: each ratio must be in (0, 1], got {list(o.window_ratios)}")
    if o.normal_radii is not None and not all(math.isfinite(r) and r > 0 for r in o.normal_radii):
        raise UsageError(f"--normal-radius: each radius must be finite and > 0, got {list(o.normal_radii)}")
    if not (isinstance(o.min_points, int) and o.min_points >= 1):
        raise UsageError(f"--required-points must be an integer >= 1, got {o.min_points!r}")
    if o.space_time_ratio is not None and not (math.isfinite(o.space_time_ratio) and o.space_time_ratio > 0):
        raise UsageError(f"--space-time-ratio must be finite and > 0, got {o.space_time_ratio!r}")
    if o.sigma_ratio is not None and not (math.isfinite(o.sigma_ratio) and o.sigma_ratio > 0):
        raise UsageError(f"--sigma-ratio must be finite and > 0, got {o.sigma_ratio!r}")
    # Nothing silently ignored (docs/errors.md): an option its mode never reads is refused, by
    # the conditions its row names (settings/series_rows.py, `needs`).
    values = {"weights": o.weights, "window_breaks": o.breaks}
    given = {name: getattr(o, name) for name in ("sigma_ratio", "space_time_ratio", "break_width", "break_min_size",
                                                 "break_penalty")}
    check_effective(parameters_of("series tam3c2"), values, given)
    if o.confidence is not None and not 0.0 < o.confidence < 1.0:
        raise UsageError(f"--confidence must be in (0, 1), got {o.confidence!r}")
    for name in ("fallback", "breaks"):
        if getattr(o, name) not in CHOICES[name]:
            flag = "--fallback" if name == "fallback" else "--window-breaks"
            raise UsageError(f"{flag} must be one of {', '.join(CHOICES[name])}, got {getattr(o, name)!r}")
    if o.break_width is not None and not (isinstance(o.break_width, int) and o.break_width >= 2):
        raise UsageError(f"--break-width must be an integer >= 2, got {o.break_width!r}")
    if o.break_min_size is not None and not (isinstance(o.break_min_size, int) and o.break_min_size >= 1):
        raise UsageError(f"--break-min-size must be an integer >= 1, got {o.break_min_size!r}")
    if o.break_penalty is not None and not (math.isfinite(o.break_penalty) and o.break_penalty > 0):
        raise UsageError(f"--break-penalty must be finite and > 0, got {o.break_penalty!r}")
    if o.lod is not None and o.lod not in LODS:
        raise UsageError(f"--lod: TAM3C2's LOD is {', '.join(LODS)} (it cannot resample a bootstrap), got {o.lod!r}")


def _reference_microseconds(view: StoreView, reference_time: str | None) -> int:
    """The reference's time: the store's, else --reference-time (for a store without one; one
    that contradicts the store's is refused); TAM3C2 needs it. A time after every epoch is said:
    each epoch is then compared with a later reference (hostile round 2: a mistyped year passed
    unnoticed)."""
    recorded = str(view.group.attrs.get("reference_time", "") or "")
    if not recorded and reference_time is None:
        raise UsageError(f"{view.shown}: its reference has no recorded time: TAM3C2 needs it; "
                         f"give --reference-time TIME")
    ours = microseconds(recorded, f"{view.shown}: reference_time") if recorded else None
    if reference_time is not None:
        given = microseconds(reference_time, "--reference-time")
        if ours is not None and given != ours:
            raise UsageError(f"--reference-time {reference_time} contradicts {view.shown}'s recorded reference time "
                             f"{recorded}: the option is for a store that has none")
        ours = given
    last = int(view.times("TAM3C2").max())
    if ours > last:
        warnings.warn(M3C2Warning(
            f"{view.shown}: the reference's time {np.datetime64(ours, 'us')} is after every epoch (the last: "
            f"{np.datetime64(last, 'us')}): each epoch is compared with a later reference; check "
            f"{'--reference-time' if reference_time is not None else 'the time given when the store was made'}"))
    return ours


def _checked_file(store: Path, path: str, sha256: str, what: str) -> tuple[Path, tuple]:
    """The recorded file, with the state it had when its SHA-256 was checked (each block re-reads it)."""
    p = Path(path)
    if not p.is_file():
        raise M3C2Error(f"{store}: {what} {p} is gone; TAM3C2 reads the epochs' files again")
    state = epoch_files.file_state(p)
    if sha256 and epoch_files.file_digest(p) != sha256:
        raise M3C2Error(f"{store}: {what} {p} changed since it was added (SHA-256 differs)")
    return p, state


def _files(view: StoreView, n: int) -> list[tuple[Path, tuple]]:
    """The reference's and the n epochs' recorded files, each checked against its SHA-256."""
    attrs = view.group.attrs
    files = [_checked_file(view.shown, attrs["reference"], attrs.get("reference_sha256", ""), "its reference")]
    info = {name: view.read(name, slice(0, n)) for name in ("source", "source_sha256") if name in view.group}
    for e in range(n):
        sha = str(info["source_sha256"][e]) if "source_sha256" in info else ""
        files.append(_checked_file(view.shown, str(info["source"][e]), sha, f"epoch {e}'s file"))
    return files


def _crops(store: Path, files, core: np.ndarray, blocks, reach: float, folder: Path) -> EpochCrops:
    """Every recorded file read once, in pool order, its points cropped to each block's box widened
    by the reach (only those can be in a sphere or cylinder of the block) and spilled
    (series/epoch_crops.py); a file written since its hash was checked is refused."""
    boxes = [(core[b:e].min(axis=0) - reach, core[b:e].max(axis=0) + reach) for b, e in blocks]
    crops = EpochCrops(folder, boxes, len(files), store)
    for path, state in files:
        xyz = read_cloud(path).xyz
        if epoch_files.file_state(path) != state:
            raise M3C2Error(f"{store}: {path} changed while TAM3C2 read it; rerun when it is written whole")
        crops.add(xyz)
        del xyz
    return crops


def _settings(view: StoreView, o: Tam3c2Options) -> tuple[dict, float]:
    """The engine's settings from the store's parameters (cylinder, normal scales, registration
    error, confidence, the LOD's statistic) and the options; and the confidence."""
    if view.imported:
        raise UsageError(f"{view.shown} was imported: its M3C2 parameters are unknown; TAM3C2 needs its cylinder")
    params = view.engine_params()
    confidence = params.confidence if o.confidence is None else o.confidence
    lod = o.lod or params.lod.name
    if lod not in LODS:
        raise UsageError(f"{view.shown}: its LOD is the {lod}, which TAM3C2 cannot resample; give --lod "
                         f"{'|'.join(LODS)}")
    radii = o.normal_radii or tuple(d / 2.0 for d in params.normal_diameters)
    settings = dict(normal_radii=[float(r) for r in radii], window_ratios=[float(r) for r in o.window_ratios],
                    min_points=int(o.min_points), cylinder_radius=params.projection_diameter / 2.0,
                    max_distance=params.max_depth, weights=o.weights, registration_error=params.registration_error,
                    lod=lod, confidence=float(confidence),
                    orientation=[0.0, 0.0, 1.0], fallback=o.fallback, breaks=o.breaks)
    defaults = facade.tam3c2_params()
    for name in ("sigma_ratio", "space_time_ratio", "break_width", "break_min_size", "break_penalty"):
        given = getattr(o, name)
        settings[name] = getattr(defaults, name) if given is None else given
    return settings, confidence


def _epochwise(view: StoreView, rows: slice, n: int, order: np.ndarray) -> dict:
    """The store's own M3C2 of the rows (distance, lod, significant, n1, n2; NaN where none) as
    the engine's pool columns: the reference's (pool position of 0 in `order`) distance 0, the
    reference against itself."""
    out = {}
    for name in facade.TAM3C2_EPOCHWISE:
        raw = view.read(name, (rows, slice(0, n)))
        values = raw.astype(np.float64)
        if name in st.INT_FILL:
            values[raw == st.INT_FILL[name][1]] = np.nan
        full = np.full((values.shape[0], n + 1), 0.0 if name == "distance" else np.nan)
        full[:, 1:] = values
        out[name] = full[:, order]
    return out


def _blocks(view: StoreView) -> list[tuple[int, int]]:
    """Core-point blocks of at most BLOCK_BYTES of results over the store's epochs."""
    return view.blocks(max(1, view.n_epochs) * 8 * 17, BLOCK_BYTES)


def tam3c2(store: Path, options: Tam3c2Options = Tam3c2Options()) -> dict:
    """Computes TAM3C2 for every core point and epoch of the store and publishes its variables."""
    _check(options)
    store = Path(store)
    threads = threads_count(options.threads)
    with ExitStack() as held, writing(store, "tam3c2", st.TAM3C2_VARIABLES, "TAM3C2 variables") as view:
        n = view.n_epochs
        if n == 0:
            raise UsageError(f"{store} has no epoch to compare")
        days = view.days("TAM3C2", since=_reference_microseconds(view, options.reference_time))
        settings, confidence = _settings(view, options)
        core = view.core()
        # Each core point's normal turned to the side of the store's (which followed its --orient),
        # so that tam3c2_distance and distance share a sign; +z where the store has no normal.
        towards = view.normals()
        reach = max(max(settings["normal_radii"]),
                    math.hypot(settings["cylinder_radius"], settings["max_distance"]))
        # The pool in time order (the engine breaks ties in time distance by pool order: the
        # earlier epoch first), the reference among the epochs where its time falls.
        times = np.array([0.0, *days])
        order = np.argsort(times, kind="stable")
        recorded = _files(view, n)
        files = [recorded[k] for k in order]
        position = np.argsort(order)  # of the reference (0) and epoch e (e + 1) in the pool
        common = {"epochs": int(n), "min_points": settings["min_points"], "weights": options.weights,
                  "window_ratios": settings["window_ratios"], "normal_radii": settings["normal_radii"],
                  "space_time_ratio": settings["space_time_ratio"], "sigma_ratio": settings["sigma_ratio"],
                  "confidence": confidence, "lod": settings["lod"], "time_unit": "days since the reference",
                  "fallback": options.fallback, "breaks": options.breaks,
                  **({k: settings[k] for k in ("break_width", "break_min_size", "break_penalty")}
                     if options.breaks != "none" else {})}
        needs_epochwise = options.fallback != "none" or options.breaks != "none"
        out = _staged_all(view, common)
        fault_hook.checkpoint("store-write")
        computed = from_epoch = 0
        blocks = _blocks(view)
        spill = held.enter_context(private_folder(store.resolve().parent, store))
        crops = _crops(store, files, core, blocks, reach, Path(spill.path))
        for k, (begin, end) in enumerate(blocks):
            pool = facade.tam3c2_pool(crops.block(k), times[order].tolist())
            rows = slice(begin, end)
            epochwise = _epochwise(view, rows, n, order) if needs_epochwise else None
            r = facade.tam3c2(pool, core[begin:end], int(position[0]), position[1:].tolist(), settings,
                              orientations=towards[begin:end], epochwise=epochwise, threads=threads)
            out[DISTANCE][rows, :n] = r["distance"]
            computed += int(np.isfinite(r["distance"]).sum())
            out[LOD][rows, :n] = r["lod"]
            out[SIGNIFICANT][rows, :n] = r["significant"]
            own = r["source"] == facade.TAM3C2_SOURCE_EPOCH
            from_epoch += int(own.sum())
            out[WINDOW][rows, :n] = np.where(own, FROM_EPOCH, np.where(
                r["source"] == facade.TAM3C2_SOURCE_WINDOWS, r["epochs1"] + r["epochs2"], -1)).astype(np.int32)
            out[N1][rows, :n] = r["n1"]
            out[N2][rows, :n] = r["n2"]
        view.publish(st.TAM3C2_VARIABLES)
    return {"epochs": n, "variables": list(st.TAM3C2_VARIABLES), "confidence": confidence, "lod": settings["lod"],
            "computed": computed, "from_epoch": from_epoch, "cells": n * len(core)}


def _staged_all(view: StoreView, common: dict) -> dict:
    spec = [(DISTANCE, np.float64, np.nan, "TAM3C2 distance (reference side to the epoch's side); where tam3c2_window is 0, the "
                                            "epoch's own M3C2 distance, LOD, significant, n1, n2"),
            (LOD, np.float64, np.nan, "TAM3C2 level of detection: z or Welch's t (attribute lod) x sqrt(s1^2/n1 + s2^2/n2) + registration error"),
            (SIGNIFICANT, np.int8, -1, "|tam3c2_distance| > tam3c2_lod (1 yes, 0 no, -1 no distance); where tam3c2_window "
                                            "is 0, the epoch's own M3C2 significant"),
            (WINDOW, np.int32, -1, "epochs aggregated, the reference's side and the epoch's side together; "
                                   "0: the epoch's own M3C2 (fallback); -1: no distance"),
            (N1, np.float64, np.nan, "points of the reference's side (Kish's effective n when weighted)"),
            (N2, np.float64, np.nan, "points of the epoch's side (Kish's effective n when weighted)")]
    out = {}
    for name, dtype, fill, long_name in spec:
        attrs = dict(common, long_name=long_name, **({"_FillValue": -1} if fill == -1 else {}))
        out[name] = view.staged(name, dtype, fill, attrs)
    return out
