"""Benchmark of `m3c2kit.register` (point-to-plane ICP, docs/registration.md) beside py4dgeo 1.2.0's
`point_to_plane_icp` on the same pair: prints time and the error against the known motion, asserts
nothing. A rough terrain of N points per epoch (seeded), the compared epoch moved by a known small
rotation and shift; no change (py4dgeo's ICP has no stable-area selection of its own in this call,
so both register on every point). py4dgeo runs in its own environment (--python) and needs its
normals computed first (Epoch.calculate_normals, both epochs: its last fit reads both), timed
with it.

    .venv/bin/python bench/registration.py --python /tmp/p4d/bin/python [--points 1000000] [--threads 2]
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
    """(rotation error in degrees, translation error at `centre`) of `matrix` against `truth`."""
    delta = matrix[:3, :3] @ truth[:3, :3].T
    angle = float(np.degrees(np.arccos(np.clip((np.trace(delta) - 1) / 2, -1, 1))))
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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--python", help="a Python with py4dgeo 1.2.0 (omit to time m3c2kit alone)")
    ap.add_argument("--points", type=int, default=1_000_000)
    ap.add_argument("--threads", type=int, default=2)
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
