"""Parameter guidance for D, d and the maximum depth (sections 5.1, 5.2.2 and 5.3).

Rules (every number behind a choice is printed):

1. Core points: `sample` reference points drawn without replacement with a fixed seed.
2. Point spacing s: the median distance from a sample of points to their nearest other point.
3. D: candidates form a geometric series (ratio sqrt 2) from 3 s up to a quarter of the cloud's
   horizontal extent (the smaller of the two largest bounding-box sides). xi = D / sigma(D) (eq. 4)
   is computed at the sampled core points on the reference; D is the smallest candidate with
   xi >= 25 at >= 95 % of them (a point without sigma(D), too few neighbours, counts as a failure).
   If none qualifies, a multi-scale range MIN:MAX:STEP is proposed, from the smallest candidate
   with xi >= 25 at >= 50 % of the points (or the smallest candidate) to the largest one, step MIN.
4. Max depth: a first M3C2 pass with D, d0 = D / 2 (D = the range's smallest scale in the
   multi-scale case) and a generous half-length H0 (the largest D candidate); the suggestion is
   3 x the 99th percentile of |distance| there, at least d0 / 2.
5. d: candidates 2 s, 2 s sqrt 2, ... up to the largest D candidate; d is the smallest with median
   n1 >= 30 and median n2 >= 30 at the core points (cylinders of the suggested max depth).
"""
from __future__ import annotations

import math

import numpy as np

from ..run import in_memory
from ..run.checks import as_points
from ..base.errors import M3C2Error, UsageError
from ..io.arrays import bounds
from .common import format_table, median_spacing, sample_indices
from .roughness import roughness_by_scale

#: Fewest reference points the rules can work with: sigma(D) needs 10 neighbours (rule 3).
MIN_POINTS = 10
XI_TARGET = 25.0
XI_SHARE = 0.95
N_TARGET = 30


def _extent(points: np.ndarray) -> float:
    lo, hi = bounds(points)
    e = np.sort(hi - lo)[::-1]
    return float(e[1]) if e[1] > 0 else float(e[0])


def _name(role: str, source) -> str:
    path = getattr(source, "path", None)
    return str(path) if path is not None else f"the {role} cloud"


def _require_a_surface(role: str, source, points: np.ndarray) -> None:
    """The rules need a surface: at least MIN_POINTS points, not all at one place."""
    if len(points) < MIN_POINTS:
        raise M3C2Error(f"{_name(role, source)}: {len(points)} points; suggest needs at least {MIN_POINTS} "
                        f"(sigma(D) is fitted to 10 neighbours, section 5.1)")
    lo, hi = bounds(points)
    extent = hi - lo
    if not np.isfinite(extent).all() or np.count_nonzero(extent) < 2:
        raise M3C2Error(f"{_name(role, source)}: the points span no surface (extent {extent.tolist()}); "
                        f"suggest needs a cloud spread over at least two axes")


def suggest(reference, compared, *, sample: int = 2000, seed: int = 0, threads: int = 0) -> dict:
    if isinstance(sample, bool) or not isinstance(sample, (int, np.integer)) or sample < 1:
        # 0 sampled nothing (numpy's "Mean of empty slice"), -1 raised numpy's ValueError
        raise UsageError(f"sample must be an integer >= 1, got {sample!r}")
    ref, cmp_ = as_points("reference", reference), as_points("compared", compared)
    _require_a_surface("reference", reference, ref)
    _require_a_surface("compared", compared, cmp_)
    core = np.ascontiguousarray(ref[sample_indices(len(ref), sample, seed)])
    s = median_spacing(ref, seed=seed)
    extent = _extent(ref)
    d_max = extent / 4
    lo = 3 * s
    count = max(1, int(math.floor(math.log(d_max / lo) / math.log(math.sqrt(2)) + 1e-9)) + 1) if d_max > lo else 1
    candidates = lo * math.sqrt(2) ** np.arange(count)
    sigma = roughness_by_scale(ref, core, candidates, min_points=10, threads=threads)
    with np.errstate(divide="ignore", invalid="ignore"):
        xi = candidates[None, :] / sigma
    share25 = np.mean(np.nan_to_num(xi, nan=0.0) >= XI_TARGET, axis=0)
    share20 = np.mean(np.nan_to_num(xi, nan=0.0) >= 20.0, axis=0)
    median_xi = np.array([np.median(c[np.isfinite(c)]) if np.isfinite(c).any() else math.nan for c in xi.T])
    if not np.isfinite(sigma).any():
        raise M3C2Error(f"{_name('reference', reference)}: no candidate D from {candidates[0]:.6g} to "
                        f"{candidates[-1]:.6g} holds {10} neighbours at any core point; the cloud is too sparse "
                        f"or too small to suggest parameters from")
    d_table = {"D": candidates, "median_xi": median_xi, "share_xi_ge_20": share20, "share_xi_ge_25": share25,
               "n_with_sigma": np.isfinite(sigma).sum(axis=0)}
    ok = np.nonzero(share25 >= XI_SHARE)[0]
    if ok.size:
        D = float(candidates[ok[0]])
        normal_scale, normal_rule = D, f"smallest D with xi >= {XI_TARGET:g} at >= {100 * XI_SHARE:g}% of core points"
    else:
        half = np.nonzero(share25 >= 0.5)[0]
        dmin = float(candidates[half[0]] if half.size else candidates[0])
        dmaxc = float(candidates[-1])
        D = dmin
        normal_scale = f"{dmin:.6g}:{dmaxc:.6g}:{dmin:.6g}" if dmaxc > dmin else dmin
        normal_rule = (f"no candidate has xi >= {XI_TARGET:g} at {100 * XI_SHARE:g}% of core points: " + (
            "multi-scale range (the most planar scale wins)" if dmaxc > dmin else
            "the largest candidate (the multi-scale range, from the first with xi >= 25 at half of them, holds "
            "only it)"))

    # Max depth from a first pass with a generous cylinder.
    h0 = float(candidates[-1])
    d0 = D / 2
    first = in_memory.compare(ref, cmp_, core, normal_scale=normal_scale, projection_scale=d0, max_depth=h0, threads=threads)
    dist = np.abs(first.distance[np.isfinite(first.distance)])
    p99 = float(np.percentile(dist, 99)) if dist.size else math.nan
    max_depth = max(3 * p99, d0 / 2) if np.isfinite(p99) else h0
    depth_info = {"first_pass_d": d0, "first_pass_depth": h0, "with_distance": int(dist.size), "p50": float(np.median(dist)) if dist.size else math.nan,
                  "p99": p99, "max_depth": max_depth,
                  "share_within": float(np.mean(dist <= max_depth)) if dist.size else math.nan}

    # Projection scale: smallest d with median n >= 30 in both clouds.
    rows = {"d": [], "median_n1": [], "median_n2": []}
    chosen = math.nan
    d = 2 * s
    d_cap = float(candidates[-1])
    while True:
        r = in_memory.compare(ref, cmp_, core, normal_scale=normal_scale, projection_scale=d, max_depth=max_depth, threads=threads)
        searched = np.isfinite(r.normal[:, 0])
        m1 = float(np.median(r.n1[searched])) if searched.any() else 0.0
        m2 = float(np.median(r.n2[searched])) if searched.any() else 0.0
        rows["d"].append(d), rows["median_n1"].append(m1), rows["median_n2"].append(m2)
        if m1 >= N_TARGET and m2 >= N_TARGET:
            chosen = d
            break
        if d >= d_cap:
            break
        d = min(d * math.sqrt(2), d_cap)
    return {"spacing": s, "extent": extent, "core_points": len(core), "normal_scale": normal_scale, "D": D,
            "normal_rule": normal_rule, "normal_table": d_table, "projection_scale": chosen,
            "projection_table": {k: np.asarray(v) for k, v in rows.items()}, "depth": depth_info}


def report_lines(res: dict) -> list[str]:
    lines = [f"{res['core_points']} sampled core points; median point spacing {res['spacing']:.4g}; "
             f"horizontal extent {res['extent']:.4g}", "", "normal scale D candidates (xi = D / sigma(D), eq. 4):"]
    lines += format_table(res["normal_table"], {"D": ".4g", "median_xi": ".3g", "share_xi_ge_20": ".3f",
                                                "share_xi_ge_25": ".3f", "n_with_sigma": "d"})
    lines.append(f"=> --normal-scale {res['normal_scale'] if isinstance(res['normal_scale'], str) else format(res['normal_scale'], '.4g')}"
                 f"  ({res['normal_rule']})")
    dep = res["depth"]
    lines += ["", f"max depth: first pass with d = {dep['first_pass_d']:.4g}, half-length {dep['first_pass_depth']:.4g}: "
                  f"{dep['with_distance']} distances, |distance| median {dep['p50']:.4g}, 99th percentile {dep['p99']:.4g}",
              f"=> --max-depth {dep['max_depth']:.4g}  (3 x the 99th percentile, at least d0 / 2; "
              f"{100 * dep['share_within']:.1f}% of first-pass |distances| within it)", "",
              f"projection scale d candidates (median points per cylinder, need >= {N_TARGET} in both):"]
    lines += format_table(res["projection_table"], {"d": ".4g", "median_n1": ".1f", "median_n2": ".1f"})
    if np.isfinite(res["projection_scale"]):
        lines.append(f"=> --projection-scale {res['projection_scale']:.4g}  (smallest d with median n1, n2 >= {N_TARGET})")
    else:
        lines.append(f"=> no d up to the largest candidate has median n1, n2 >= {N_TARGET}: the clouds are too sparse; "
                     "use the largest d shown")
    return lines


def round_sig(value: float, digits: int = 2, up: bool = False) -> float:
    """`value` to `digits` significant digits (rounded up with `up`: a depth must not shrink)."""
    if not math.isfinite(value) or value == 0:
        return value
    k = math.floor(math.log10(abs(value))) - digits + 1
    q = value / 10**k
    q = math.ceil(q - 1e-9) if up else round(q)
    return float(f"{q * 10**k:.{max(0, -k)}f}")


#: At most this many scales in a proposed multi-scale range.
MAX_PROPOSED_SCALES = 8


def proposal(res: dict, reference: str = "REFERENCE", compared: str = "COMPARED",
             output: str = "change.laz") -> dict:
    """The choices of :func:`suggest` rounded to 2 significant digits (the depth rounded up), a
    multi-scale range of at most MAX_PROPOSED_SCALES scales, and the command line to run."""
    spec = res["normal_scale"]
    if isinstance(spec, str):
        lo, hi, _ = (float(v) for v in spec.split(":"))
        lo, hi = round_sig(lo), round_sig(hi)
        step = round_sig(max((hi - lo) / (MAX_PROPOSED_SCALES - 1), lo), up=True)
        normal = f"{lo:g}:{hi:g}:{step:g}"
    else:
        normal = f"{round_sig(float(spec)):g}"
    d = res["projection_scale"]
    if not math.isfinite(d):
        d = float(res["projection_table"]["d"][-1])
    d = round_sig(d)
    depth = round_sig(res["depth"]["max_depth"], up=True)
    command = (f"m3c2 compare {reference} {compared} -o {output} --normal-scale {normal} "
               f"--projection-scale {d:g} --max-depth {depth:g}")
    return {"normal_scale": normal, "projection_scale": d, "max_depth": depth, "command": command}


def proposal_lines(res: dict, reference: str, compared: str) -> list[str]:
    p = proposal(res, reference, compared)
    return ["", f"proposal (rounded): --normal-scale {p['normal_scale']} --projection-scale "
                f"{p['projection_scale']:g} --max-depth {p['max_depth']:g}", "command to run:", f"  {p['command']}"]
