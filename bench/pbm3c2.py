"""Benchmark of `m3c2kit.pbm3c2` (PB-M3C2, docs/validation.md "PB-M3C2") beside py4dgeo 1.2.0's
`PBM3C2` on shared inputs: the same two xyz files (x y z segment_id, the segments given to both)
and the same training file, for the nearest-neighbour rule (with and without the mutual filter)
and the random forest. Prints per run the pairs (the same? correct against the truth? which did
our plane-misfit rule refuse?), the
distances (ours and theirs against the truth, and theirs recomputed from our segment tables with
their formula), the LODs (theirs recomputed from our columns with their formula) and the times
with their ratio. Asserts nothing.

    .venv/bin/python bench/pbm3c2.py --python /tmp/p4d/bin/python [--sizes 100 1000 5000] [--threads 0]

The scene: S facets 1 m square, 200 points each per epoch, 3 m apart on a grid, tilted up to
25 deg from the vertical, 3 mm noise; 30 % unchanged, the others moved 5-100 mm along their
normal. Every 10th facet (from the 3rd) is seen over half its area in the compared epoch and
rotated 3 deg about its centre there (the distance is then not the centroids' offset along n1);
every 20th (from the 6th) is absent in the compared epoch (its neighbours, 3 m away, are within
the search radius 3.5 m: a wrong pair unless a filter or the forest refuses it). The training
file: the first 10 % of the facets with their own compared facet (1) and with the next one (0).
py4dgeo runs in its own interpreter (a separate venv); the times exclude reading the files.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

SEED = 17
POINTS = 200  # per facet and epoch
SPACING, SIZE, NOISE, MAX_TILT = 3.0, 1.0, 0.003, 25.0
SEARCH_RADIUS = 3.5
#: Ours, theirs: (our correspondence, mutual), (their method, filter).
RUNS = {"nearest": (("nearest", False), ("nearest_neighbor", "none")),
        "nearest, mutual": (("nearest", True), ("nearest_neighbor", "mutual_nearest_neighbors")),
        "random forest": (("forest", False), ("random_forest", "none"))}
#: Our PairStatus for a compared plane off its own points under the reference segment.
MISFIT = 5


def frame(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = np.cross([1.0, 0.0, 0.0], n)
    a /= np.linalg.norm(a)
    return a, np.cross(n, a)


def rotate(v: np.ndarray, axis: np.ndarray, degrees: float) -> np.ndarray:
    """v rotated about the unit `axis` (Rodrigues)."""
    t = math.radians(degrees)
    return v * math.cos(t) + np.cross(axis, v) * math.sin(t) + axis * np.dot(axis, v) * (1 - math.cos(t))


def scene(segments: int, seed: int = SEED) -> dict:
    """Both epochs, their segment ids, and per facet: the true compared plane (a point, a normal)
    and its kind (full, half: half seen and rotated, absent)."""
    rng = np.random.default_rng(seed)
    cols = math.ceil(math.sqrt(segments))
    ref, cmp_, ref_ids, cmp_ids, planes, kinds = [], [], [], [], [], []
    for k in range(segments):
        tilt, azimuth = math.radians(rng.uniform(0, MAX_TILT)), rng.uniform(0, 2 * math.pi)
        n = np.array([math.sin(tilt) * math.cos(azimuth), math.sin(tilt) * math.sin(azimuth), math.cos(tilt)])
        a, b = frame(n)
        centre = np.array([SPACING * (k % cols), SPACING * (k // cols), rng.uniform(-0.3, 0.3)])
        move = 0.0 if rng.random() < 0.3 else rng.uniform(0.005, 0.1) * rng.choice((-1.0, 1.0))
        kind = "absent" if k % 20 == 5 else "half" if k % 10 == 2 else "full"
        u, v = rng.uniform(-SIZE / 2, SIZE / 2, (2, POINTS))
        ref.append(centre + u[:, None] * a + v[:, None] * b + rng.normal(0, NOISE, POINTS)[:, None] * n)
        ref_ids.append(np.full(POINTS, k))
        n2, a2 = (rotate(n, b, 3.0), rotate(a, b, 3.0)) if kind == "half" else (n, a)
        planes.append((centre, centre + move * n, n2, n))
        kinds.append(kind)
        if kind == "absent":
            continue
        u = rng.uniform(-SIZE / 2, 0.0 if kind == "half" else SIZE / 2, POINTS)
        v = rng.uniform(-SIZE / 2, SIZE / 2, POINTS)
        cmp_.append(centre + move * n + u[:, None] * a2 + v[:, None] * b + rng.normal(0, NOISE, POINTS)[:, None] * n2)
        cmp_ids.append(np.full(POINTS, k))
    return {"ref": np.vstack(ref), "cmp": np.vstack(cmp_), "ref_ids": np.concatenate(ref_ids),
            "cmp_ids": np.concatenate(cmp_ids), "planes": planes, "kinds": np.array(kinds)}


def truth_at(s: dict, k: int, c1: np.ndarray) -> float:
    """The true change of facet k where the reference centroid c1 is: along the true normal n from
    c1's foot on the true reference plane to the true compared plane (normals up: the move's sign)."""
    centre, point, n2, n = s["planes"][k]
    foot = c1 - np.dot(c1 - centre, n) * n
    return float(np.dot(point - foot, n2) / np.dot(n, n2))


def training(segments: int) -> np.ndarray:
    """The first 10 % of the facets (not absent ones): with their own compared facet 1, the next 0."""
    rows = []
    for k in range(max(2, segments // 10)):
        if k % 20 == 5 or (k + 1) % 20 == 5:
            continue
        rows += [(k, k, 1), (k, k + 1, 0)]
    return np.array(rows, dtype=np.int64)


def write_xyz(path: Path, xyz: np.ndarray, ids: np.ndarray) -> None:
    """x y z segment_id, the coordinates printed exactly (17 significant digits): both tools read
    the same doubles."""
    with open(path, "w") as f:
        f.write("x y z segment_id\n")
        np.savetxt(f, np.column_stack([xyz, ids]), fmt=["%.17g", "%.17g", "%.17g", "%d"])


def py4dgeo_child(spec_path: str) -> None:
    """Runs in py4dgeo's interpreter: its PBM3C2.run for each run of the spec; JSON to spec's out."""
    import contextlib
    import io

    import py4dgeo
    spec = json.loads(Path(spec_path).read_text())
    py4dgeo.set_num_threads(spec["threads"]) if spec["threads"] else None
    epochs = [py4dgeo.read_from_xyz(p, additional_dimensions={3: "segment_id"},
                                    additional_dimensions_dtypes={"segment_id": np.int64}, skip_header=1)
              for p in (spec["ref"], spec["cmp"])]
    out = {"version": py4dgeo.__version__}
    for name, run in spec["runs"].items():
        algorithm = py4dgeo.PBM3C2(registration_error=run["registration_error"])
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            t0 = time.perf_counter()
            df = algorithm.run(epochs[0], epochs[1], correspondences_file=run["training"],
                               search_radius=run["search_radius"], correspondence_method=run["method"],
                               correspondence_filter=run["filter"])
            seconds = time.perf_counter() - t0
        out[name] = {"seconds": seconds, "ref": df["epoch0_original_id"].astype(int).tolist(),
                     "cmp": df["epoch1_original_id"].astype(int).tolist(), "distance": df["distance"].tolist(),
                     "uncertainty": df["uncertainty"].tolist()}
    Path(spec["out"]).write_text(json.dumps(out))


def run_theirs(python: str, folder: Path, runs: dict, threads: int) -> dict:
    spec = folder / "spec.json"
    spec.write_text(json.dumps({"ref": str(folder / "ref.xyz"), "cmp": str(folder / "cmp.xyz"), "runs": runs,
                                "threads": threads, "out": str(folder / "theirs.json")}))
    done = subprocess.run([python, __file__, "--child", str(spec)], capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"py4dgeo failed: {done.stderr.strip()[-2000:]}")
    return json.loads((folder / "theirs.json").read_text())


def run_ours(folder: Path, correspondence: str, mutual: bool, registration_error: float, threads: int):
    import warnings

    import m3c2kit
    from m3c2kit.io import read_cloud
    clouds = [read_cloud(folder / name) for name in ("ref.xyz", "cmp.xyz")]
    options = {"correspondence": correspondence, "search_radius": SEARCH_RADIUS, "threads": threads,
               "registration_error": registration_error}
    if correspondence == "forest":
        options["training"] = np.loadtxt(folder / "training.csv", delimiter=",", ndmin=2)
        import sklearn.ensemble  # noqa: F401  imported before the clock, as `import py4dgeo` imports it
    else:
        options["mutual"] = mutual
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0 = time.perf_counter()
        result = m3c2kit.pbm3c2(clouds[0], clouds[1], reference_segments=clouds[0].fields["segment_id"],
                                compared_segments=clouds[1].fields["segment_id"], **options)
        return result, time.perf_counter() - t0


def engine_only(s: dict, threads: int) -> float:
    """Our engine's share: the planes, the pairs and the changes (what m3c2kit.pbm3c2 adds: the
    checks, m3c2 suggest's D for the search radius's floor, the table)."""
    from m3c2kit.engine import planes
    t0 = time.perf_counter()
    ref = planes.plane_segments(s["ref"], s["ref_ids"], threads=threads)
    cmp_ = planes.plane_segments(s["cmp"], s["cmp_ids"], threads=threads)
    found = planes.nearest_segments(ref, cmp_, {"search_radius": SEARCH_RADIUS})
    planes.plane_changes(ref, cmp_, found["compared"], {"confidence": 0.95})
    return time.perf_counter() - t0


def compare(s: dict, result, theirs: dict, registration_error: float) -> dict:
    """The pairs, distances and LODs of one run, ours beside theirs."""
    p = result.pairs
    ours = {int(r): (k, int(c)) for k, (r, c, st) in
            enumerate(zip(p["reference_segment"], p["compared_segment"], p["status"])) if st == 0}
    their = {r: (k, c) for k, (r, c) in enumerate(zip(theirs["ref"], theirs["cmp"]))}
    same = [r for r in ours if r in their and ours[r][1] == their[r][1]]
    # Our rows refused because the compared plane is off its own points there (status 5): true
    # pairs (the facet's own compared segment) or wrong ones (a neighbour of an absent facet).
    misfit = p["status"] == MISFIT
    refused_true = int(np.count_nonzero(misfit & (p["compared_segment"] == p["reference_segment"])))
    out = {"ours": len(ours), "theirs": len(their), "same": len(same),
           "only_ours": sum(r not in their for r in ours), "only_theirs": sum(r not in ours for r in their),
           "differ": sum(r in their and ours[r][1] != their[r][1] for r in ours),
           "ours_wrong": sum(c != r for r, (_, c) in ours.items()),
           "theirs_wrong": sum(c != r for r, (_, c) in their.items()),
           "misfit_true": refused_true, "misfit_wrong": int(np.count_nonzero(misfit)) - refused_true}
    # Distances on the correct pairs both found: against the truth, and theirs' formula on our tables.
    ref_t, cmp_t = result.reference_segments, result.compared_segments
    cmp_row = {int(label): k for k, label in enumerate(cmp_t["label"])}
    # A different pair: is their compared plane beyond our angle gate (max_angle, 30 deg)?
    normals1, normals2 = np.asarray(ref_t["normal"]), np.asarray(cmp_t["normal"])
    out["differ_gated"] = sum(
        abs(np.dot(normals1[ours[r][0]], normals2[cmp_row[their[r][1]]])) < math.cos(math.radians(30.0))
        for r in ours if r in their and ours[r][1] != their[r][1])
    errors = {"full": ([], []), "half": ([], [])}
    formula, sign_agree, lod_gap, lod_ratio = [], [], [], []
    for r in same:
        if ours[r][1] != r:
            continue
        k, j = ours[r][0], their[r][0]
        c1, n1 = np.asarray(ref_t["centroid"])[k], np.asarray(ref_t["normal"])[k]
        c2 = np.asarray(cmp_t["centroid"])[cmp_row[r]]
        truth = truth_at(s, r, c1)
        d_ours, d_theirs = p["distance"][k], theirs["distance"][j]
        sign_agree.append(np.sign(d_ours) == np.sign(d_theirs) or d_ours == 0)
        kind = s["kinds"][r]
        errors[kind][0].append(abs(d_ours - truth))
        errors[kind][1].append(abs(abs(d_theirs) - abs(truth)))
        formula.append(abs(abs(d_theirs) - abs(np.dot(c2 - c1, n1))))
        # Their LOD from our columns: np.std (ddof 0) = ours * sqrt((n - 3) / n), 1.96, reg outside
        # the critical value, no lever, no 1/cos.
        n1_, n2_ = p["n1"][k], p["n2"][k]
        s1 = p["roughness1"][k] ** 2 * (n1_ - 3) / n1_
        s2 = p["roughness2"][k] ** 2 * (n2_ - 3) / n2_
        predicted = 1.96 * math.sqrt(s1 / n1_ + s2 / n2_) + registration_error
        lod_gap.append(abs(theirs["uncertainty"][j] - predicted) / predicted)
        lod_ratio.append((theirs["uncertainty"][j] / p["lod"][k], kind))
    out.update(errors=errors, formula=max(formula, default=math.nan), sign_agree=float(np.mean(sign_agree)),
               lod_gap=max(lod_gap, default=math.nan), lod_ratio=lod_ratio)
    return out


def table_line(name: str, c: dict) -> list[str]:
    def mx(values):
        return f"{max(values) * 1e3:.3f}" if values else "-"

    full_ratio = [v for v, kind in c["lod_ratio"] if kind == "full"]
    half_ratio = [v for v, kind in c["lod_ratio"] if kind == "half"]
    return [
        f"  {name}: pairs ours {c['ours']}, theirs {c['theirs']}: the same {c['same']}, different {c['differ']} "
        f"({c['differ_gated']} of them: their plane beyond our 30 deg gate), "
        f"only ours {c['only_ours']}, only theirs {c['only_theirs']}; wrong pairs (another facet): ours "
        f"{c['ours_wrong']}, theirs {c['theirs_wrong']}; ours refused as plane misfits (status 5): "
        f"{c['misfit_true']} true pairs, {c['misfit_wrong']} wrong ones",
        f"    |d - truth| max, full facets: ours {mx(c['errors']['full'][0])} mm, theirs {mx(c['errors']['full'][1])} "
        f"mm (|d|); half seen + rotated 3 deg: ours {mx(c['errors']['half'][0])} mm, theirs "
        f"{mx(c['errors']['half'][1])} mm",
        f"    their |d| = |(c2 - c1) . n1| from our tables within {c['formula']:.1e} m; the same sign "
        f"{c['sign_agree']:.0%} (their normal's sign is arbitrary)",
        f"    their LOD = 1.96 sqrt(s1'^2/n1 + s2'^2/n2) + reg with s' = np.std from our columns within "
        f"{c['lod_gap']:.1e} (relative); theirs / ours: full facets median "
        f"{np.median(full_ratio) if full_ratio else math.nan:.4f}, half + rotated median "
        f"{np.median(half_ratio) if half_ratio else math.nan:.3f}"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--python", default=os.environ.get("PY4DGEO_PYTHON"),
                    help="a Python with py4dgeo 1.2.0 (omit to time m3c2kit alone)")
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 1000, 5000], help="segments per epoch")
    ap.add_argument("--threads", type=int, default=0, help="ours (0: every core); py4dgeo's PBM3C2 is Python")
    ap.add_argument("--registration-error", type=float, default=0.002,
                    help="reg for an extra nearest run at the first size (default 0.002 m)")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        py4dgeo_child(args.child)
        return 0
    print(f"PB-M3C2: facets of {POINTS} points, search radius {SEARCH_RADIUS} m, ours with {args.threads or 'all'} "
          f"threads ({os.cpu_count()} cores)")
    timings = []
    for size in args.sizes:
        s = scene(size)
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp)
            write_xyz(folder / "ref.xyz", s["ref"], s["ref_ids"])
            write_xyz(folder / "cmp.xyz", s["cmp"], s["cmp_ids"])
            np.savetxt(folder / "training.csv", training(size), fmt="%d", delimiter=",")
            runs = {name: (ours, (method, filt), 0.0) for name, (ours, (method, filt)) in RUNS.items()}
            if size == args.sizes[0]:
                runs[f"nearest, reg {args.registration_error * 1e3:g} mm"] = (("nearest", False),
                                                                              ("nearest_neighbor", "none"),
                                                                              args.registration_error)
            theirs = {}
            if args.python:
                theirs = run_theirs(args.python, folder, {
                    name: {"method": m, "filter": f, "registration_error": reg, "search_radius": SEARCH_RADIUS,
                           "training": str(folder / "training.csv") if m == "random_forest" else None}
                    for name, (_, (m, f), reg) in runs.items()}, args.threads)
            kinds = {k: int(np.count_nonzero(s["kinds"] == k)) for k in ("full", "half", "absent")}
            print(f"\n{size} segments ({len(s['ref']):,} / {len(s['cmp']):,} points; {kinds['full']} full, "
                  f"{kinds['half']} half seen and rotated, {kinds['absent']} absent in the compared epoch)")
            for name, ((correspondence, mutual), _, reg) in runs.items():
                result, seconds = run_ours(folder, correspondence, mutual, reg, args.threads)
                line = f"  {name}: ours {seconds:.2f} s"
                if name in theirs:
                    line += f", py4dgeo {theirs[name]['seconds']:.2f} s: {theirs[name]['seconds'] / seconds:.1f}x"
                    timings.append((size, name, seconds, theirs[name]["seconds"]))
                print(line)
                if name in theirs:
                    print("\n".join(table_line(name, compare(s, result, theirs[name], reg))))
            print(f"  our engine alone (planes, nearest pairs, changes): {engine_only(s, args.threads):.3f} s")
    if timings:
        print("\nTimes (s)      segments  run                 ours    py4dgeo   py4dgeo / ours")
        for size, name, ours, their in timings:
            print(f"               {size:>8}  {name:<18} {ours:7.2f}  {their:8.2f}   {their / ours:6.1f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
