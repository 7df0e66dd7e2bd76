"""Benchmark of `m3c2kit.register` (point-to-plane ICP, docs/registration.md) beside py4dgeo 1.2.0's
`point_to_plane_icp` on the same pair: prints time and the error against the known motion, asserts
nothing. A rough terrain of N points per epoch (seeded), the compared epoch moved by a known small
rotation and shift; no change (py4dgeo's ICP has no stable-area selection of its own in this call,
so both register on every point). py4dgeo runs in its own environment (--python) and needs its
normals computed first (Epoch.calculate_normals, both epochs: its last fit reads both), timed
with it.

    .venv/bin/python bench/registration.py --python /tmp/p4d/bin/python [--points 1000000] [--threads 2] \\
        [--cloudcompare CloudCompare]

--cloudcompare runs CloudCompare's ICP (its command line, -SILENT; Debian 12's cloudcompare 2.11.3,
under QT_QPA_PLATFORM=offscreen) on the same pair written as ASCII: point-to-point ICP (Besl &
McKay 1992) on a random sample of the compared cloud (-RANDOM_SAMPLING_LIMIT, CloudCompare's
default 20000 and 50000), stopping when the error changes by less than 1e-9. Its time is the
whole command's less a run that only loads the two files.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

SEED = 11
ROTATION_DEG = (0.3, -0.2, 0.5)
SHIFT = (0.08, -0.05, 0.04)


def terrain(rng, n: int) -> np.ndarray:
    xy = rng.uniform(0, 100, (n, 2))
    z = 2 * np.sin(xy[:, 0] / 9) + 1.5 * np.cos(xy[:, 1] / 7) + 0.3 * np.sin((xy[:, 0] + xy[:, 1]) / 3)
    return np.column_stack([xy, z + rng.normal(0, 0.002, n)])


def rotation(degrees) -> np.ndarray:
    ax, ay, az = np.radians(degrees)
    rx = np.array([[1, 0, 0], [0, np.cos(ax), -np.sin(ax)], [0, np.sin(ax), np.cos(ax)]])
    ry = np.array([[np.cos(ay), 0, np.sin(ay)], [0, 1, 0], [-np.sin(ay), 0, np.cos(ay)]])
    rz = np.array([[np.cos(az), -np.sin(az), 0], [np.sin(az), np.cos(az), 0], [0, 0, 1]])
    return rz @ ry @ rx


def errors(matrix: np.ndarray, truth: np.ndarray, centre: np.ndarray) -> tuple[float, float]:
    """(rotation error in degrees, translation error at `centre`) of `matrix` against `truth`. The
    angle is that of the nearest rotation (SVD; CloudCompare's float32 matrices are not orthonormal:
    singular values 1 + 1e-6, so a trace above 3 would read as no error at all), by atan2 of the
    skew part's norm and the cosine: exact near 0, where arccos of the cosine loses half the digits."""
    u, _, vt = np.linalg.svd(matrix[:3, :3])
    delta = (u @ vt) @ truth[:3, :3].T
    skew = np.array([delta[2, 1] - delta[1, 2], delta[0, 2] - delta[2, 0], delta[1, 0] - delta[0, 1]]) / 2
    angle = float(np.degrees(np.arctan2(np.linalg.norm(skew), (np.trace(delta) - 1) / 2)))
    moved = matrix[:3, :3] @ centre + matrix[:3, 3] - (truth[:3, :3] @ centre + truth[:3, 3])
    return angle, float(np.linalg.norm(moved))


PY4DGEO = """
import json, sys, time
import numpy as np
import py4dgeo
py4dgeo.set_num_threads({threads})
ref, cmp_ = np.load({ref!r}), np.load({cmp!r})
t0 = time.perf_counter()
reference, compared = py4dgeo.Epoch(ref), py4dgeo.Epoch(cmp_)
reference.calculate_normals(radius={radius})
compared.calculate_normals(radius={radius})  # its final fit reads the compared epoch's normals too
trafo = py4dgeo.point_to_plane_icp(reference, compared)
seconds = time.perf_counter() - t0
print(json.dumps({{"seconds": seconds, "matrix": np.asarray(trafo.affine_transformation).tolist(),
                   "reduction_point": np.asarray(trafo.reduction_point).ravel().tolist()}}))
"""


def cloudcompare(executable: str, ref: np.ndarray, cmp_: np.ndarray, sampling: int) -> tuple[np.ndarray, float]:
    """(the 4x4 matrix moving `cmp_` onto `ref`, seconds) of CloudCompare's ICP on the pair."""
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen")
    with tempfile.TemporaryDirectory() as tmp:
        ref_path, cmp_path = os.path.join(tmp, "ref.xyz"), os.path.join(tmp, "cmp.xyz")
        np.savetxt(ref_path, ref, fmt="%.6f")
        np.savetxt(cmp_path, cmp_, fmt="%.6f")
        common = [executable, "-SILENT", "-NO_TIMESTAMP", "-AUTO_SAVE", "OFF", "-O", cmp_path, "-O", ref_path]
        t0 = time.perf_counter()
        subprocess.run(common, env=env, capture_output=True, check=True)
        loading = time.perf_counter() - t0
        t0 = time.perf_counter()
        # The first cloud opened is registered onto the second (CloudCompare's -ICP: data, then model).
        subprocess.run(common + ["-ICP", "-MIN_ERROR_DIFF", "1e-9", "-RANDOM_SAMPLING_LIMIT", str(sampling)],
                       env=env, capture_output=True, check=True)
        seconds = time.perf_counter() - t0 - loading
        matrix = np.loadtxt(os.path.join(tmp, "cmp_REGISTRATION_MATRIX.txt"))
    return matrix, seconds


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--python", help="a Python with py4dgeo 1.2.0 (omit to time m3c2kit alone)")
    ap.add_argument("--points", type=int, default=1_000_000)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--cloudcompare", metavar="EXECUTABLE", help="also CloudCompare's ICP (its command line)")
    args = ap.parse_args(argv)
    import m3c2kit
    rng = np.random.default_rng(SEED)
    ref, cmp_true = terrain(rng, args.points), terrain(rng, args.points)
    truth = np.eye(4)  # compared -> reference
    truth[:3, :3], truth[:3, 3] = rotation(ROTATION_DEG), SHIFT
    inverse = np.linalg.inv(truth)
    cmp_ = cmp_true @ inverse[:3, :3].T + inverse[:3, 3]  # the compared epoch, moved away by the inverse
    centre = ref.mean(axis=0)
    print(f"{args.points:,} points per epoch, motion {ROTATION_DEG} deg and {SHIFT}, {args.threads} threads")
    t0 = time.perf_counter()
    ours = m3c2kit.register(ref, cmp_, normal_scale=2.0, threads=args.threads)
    seconds = time.perf_counter() - t0
    angle, shift = errors(ours.matrix, truth, centre)
    print(f"m3c2kit.register   {seconds:8.2f} s   rotation error {angle:.2e} deg   translation error {shift * 1e3:.3f} mm"
          f"   ({ours.details.get('iterations')} iterations, reg {ours.registration_error * 1e3:.2f} mm)")
    if args.cloudcompare:
        for sampling in (20_000, 50_000):
            matrix, cc_seconds = cloudcompare(args.cloudcompare, ref, cmp_, sampling)
            angle, shift = errors(matrix, truth, centre)
            print(f"CloudCompare ICP   {cc_seconds:8.2f} s   rotation error {angle:.2e} deg   translation error "
                  f"{shift * 1e3:.3f} mm   (point-to-point, {sampling:,} sampled points; "
                  f"CloudCompare / m3c2kit {cc_seconds / seconds:.1f}x)")
    if not args.python:
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        paths = os.path.join(tmp, "ref.npy"), os.path.join(tmp, "cmp.npy")
        np.save(paths[0], ref)
        np.save(paths[1], cmp_)
        code = PY4DGEO.format(threads=args.threads, ref=paths[0], cmp=paths[1], radius=1.0)
        out = subprocess.run([args.python, "-c", code], capture_output=True, text=True)
    if out.returncode != 0:
        print(f"py4dgeo failed: {out.stderr.strip().splitlines()[-1] if out.stderr.strip() else out.returncode}")
        return 0
    theirs = json.loads(out.stdout.strip().splitlines()[-1])
    matrix, rp = np.array(theirs["matrix"]), np.array(theirs["reduction_point"])
    about_origin = np.eye(4)  # py4dgeo's p' = A (p - r) + t + r, as a matrix about the origin
    about_origin[:3, :3], about_origin[:3, 3] = matrix[:3, :3], matrix[:3, 3] + rp - matrix[:3, :3] @ rp
    angle, shift = errors(about_origin, truth, centre)
    print(f"py4dgeo p2p ICP    {theirs['seconds']:8.2f} s   rotation error {angle:.2e} deg   translation error "
          f"{shift * 1e3:.3f} mm   (normals included)")
    print(f"ratio (py4dgeo / m3c2kit): {theirs['seconds'] / seconds:.1f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
