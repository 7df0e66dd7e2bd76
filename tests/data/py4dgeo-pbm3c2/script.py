# A py4dgeo PBM3C2 user script (py4dgeo 1.2.0's tutorial steps on a scene of its own): 40 tilted
# facets of a rock face, pre-segmented, the second epoch moved along each facet's normal by a
# known amount. tests/python/compat/test_compat_pbm3c2.py runs it with only the import changed;
# validation/make_py4dgeo_pbm3c2_golden.py runs it with py4dgeo itself (golden.npz).
import numpy as np

import py4dgeo

FACETS, POINTS = 40, 500
SHIFTS = np.linspace(-0.05, 0.05, FACETS)


def facets(shifts, seed):
    rng = np.random.default_rng(seed)
    out = []
    for k, shift in enumerate(shifts):
        tilt = np.radians(25 if k % 2 else -15)
        normal = np.array([np.sin(tilt), -np.cos(tilt), 0.3])
        normal /= np.linalg.norm(normal)
        u = np.cross([0, 0, 1], normal)
        u /= np.linalg.norm(u)
        v = np.cross(normal, u)
        a, b = rng.uniform(-1, 1, (POINTS, 1)), rng.uniform(-1, 1, (POINTS, 1))
        h = rng.normal(0, 0.005, (POINTS, 1)) + shift
        out.append(np.array([3.0 * (k % 10), 3.0 * (k // 10), 0.0]) + a * u + b * v + h * normal)
    return np.vstack(out)


ids = np.repeat(np.arange(FACETS), POINTS)
np.savetxt("epoch0.xyz", np.c_[facets(np.zeros(FACETS), 1), ids + 100])
np.savetxt("epoch1.xyz", np.c_[facets(SHIFTS, 2), ids + 500])
with open("correspondences.csv", "w") as f:  # facets 0-27 labelled: each with itself and its neighbour
    for i in range(28):
        for j in (i, (i + 1) % FACETS):
            f.write(f"{i + 100},{j + 500},{int(i == j)}\n")

epoch0 = py4dgeo.read_from_xyz("epoch0.xyz", additional_dimensions={3: "segment_id"}, delimiter=" ")
epoch1 = py4dgeo.read_from_xyz("epoch1.xyz", additional_dimensions={3: "segment_id"}, delimiter=" ")
apply_ids = np.arange(128, 140)

alg = py4dgeo.PBM3C2(registration_error=0.01)
forest = alg.run(epoch0=epoch0, epoch1=epoch1, correspondences_file="correspondences.csv", apply_ids=apply_ids,
                 search_radius=5.0)

alg_nn = py4dgeo.PBM3C2(registration_error=0.01)
nearest = alg_nn.run(epoch0=epoch0, epoch1=epoch1, correspondences_file=None, apply_ids=apply_ids,
                     search_radius=5.0, correspondence_method="nearest_neighbor",
                     correspondence_filter="mutual_nearest_neighbors")
metrics = alg_nn.epoch0_segment_metrics
