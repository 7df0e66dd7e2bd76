"""Issue 43: py4dgeo user scripts run twice, with `import py4dgeo` (py4dgeo 1.2.0, in its own
environment) and with only that line changed to `import m3c2kit.compat.py4dgeo as py4dgeo`;
prints, per script, whether both ran and how far their numbers are apart. Asserts nothing (a
validation table for docs/validation.md).

    .venv/bin/python validation/compat_py4dgeo_scripts.py --py4dgeo-python /tmp/p4d/bin/python
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
TUTORIAL = REPO / "tests" / "data" / "py4dgeo-tutorial"

#: name -> the script's body after its import line; it leaves its results in `out` (name -> array).
SCRIPTS = {
    "tutorial, one scale": """
        e1, e2 = py4dgeo.read_from_xyz(T1, T2)
        m = py4dgeo.M3C2(epochs=(e1, e2), corepoints=e1.cloud[::7], normal_radii=[1.5], cyl_radius=1.0,
                         max_distance=3.0)
        d, u = m.run()
        out = {"distance": d, "lod": u["lodetection"], "n1": u["num_samples1"]}""",
    "multi-scale normals": """
        e1, e2 = py4dgeo.read_from_xyz(T1, T2)
        m = py4dgeo.M3C2(epochs=(e1, e2), corepoints=e1.cloud[::7], normal_radii=[0.5, 1.0, 2.0], cyl_radius=1.0)
        d, u = m.run()
        out = {"distance": d, "radii": m.directions_radii()}""",
    "robust aggregation": """
        e1, e2 = py4dgeo.read_from_xyz(T1, T2)
        d, u = py4dgeo.M3C2(epochs=(e1, e2), corepoints=e1.cloud[::7], normal_radii=[1.5], cyl_radius=1.0,
                            max_distance=3.0, robust_aggr=True).run()
        out = {"distance": d}""",
    "oblique orientation vector": """
        e1, e2 = py4dgeo.read_from_xyz(S1, S2)
        m = py4dgeo.M3C2(epochs=(e1, e2), corepoints=e1.cloud[::40], normal_radii=[1.0], cyl_radius=0.5,
                         max_distance=1.0, orientation_vector=np.array([-1.0, 0.0, 1.0]))
        d, u = m.run()
        out = {"distance": d, "normals": m.directions()}""",
    "given normals, one for all": """
        e1, e2 = py4dgeo.read_from_xyz(S1, S2)
        d, u = py4dgeo.M3C2(epochs=(e1, e2), corepoints=e1.cloud[::40], cyl_radius=0.5, max_distance=1.0,
                            corepoint_normals=np.array([[0.0, 0.0, 1.0]])).run()
        out = {"distance": d}""",
    "subclass overriding directions()": """
        class Vertical(py4dgeo.M3C2):
            def directions(self):
                return np.array([[0.0, 0.0, 1.0]])
        e1, e2 = py4dgeo.read_from_xyz(S1, S2)
        d, u = Vertical(epochs=(e1, e2), corepoints=e1.cloud[::40], normal_radii=[1.0], cyl_radius=0.5,
                        max_distance=1.0).run()
        out = {"distance": d}""",
    "normals from a third cloud": """
        e1, e2 = py4dgeo.read_from_xyz(S1, S2)
        third = py4dgeo.Epoch(e1.cloud[::2].copy())
        m = py4dgeo.M3C2(epochs=(e1, e2), corepoints=e1.cloud[::40], normal_radii=[1.0], cyl_radius=0.5,
                         max_distance=1.0, cloud_for_normals=third)
        d, u = m.run()
        out = {"distance": d}""",
    "transform then compare": """
        e1, e2 = py4dgeo.read_from_xyz(S1, S2)
        e2.transform(rotation=np.eye(3), translation=np.array([0.0, 0.0, -0.05]))
        d, u = py4dgeo.M3C2(epochs=(e1, e2), corepoints=e1.cloud[::40], normal_radii=[1.0], cyl_radius=0.5,
                            max_distance=1.0).run()
        out = {"distance": d}""",
    "Epoch.calculate_normals": """
        e1, e2 = py4dgeo.read_from_xyz(S1, S2)
        out = {"normals": e1.calculate_normals(radius=1.0, orientation_vector=np.array([0.0, 0.0, 1.0]))[::50]}""",
    "timestamps": """
        e = py4dgeo.Epoch(np.zeros((3, 3)), timestamp="2024-05-01T12:30:00")
        out = {"timestamp": np.array([str(e.timestamp)]), "day_of_year": np.array([str(
            py4dgeo.Epoch(np.zeros((3, 3)), timestamp=(2024, 32)).timestamp)])}""",
    "regular core point grid": """
        out = {"grid": py4dgeo.regular_corepoint_grid((0.0, 0.0), (1.0, 2.0), (3, 3), zval=5.0)}""",
    "results to LAS": """
        e1, e2 = py4dgeo.read_from_xyz(T1, T2)
        m = py4dgeo.M3C2(epochs=(e1, e2), corepoints=e1.cloud[::7], normal_radii=[1.5], cyl_radius=1.0,
                         max_distance=3.0)
        d, u = m.run()
        py4dgeo.write_m3c2_results_to_las(OUT + ".las", m, {"distances": d})
        back = py4dgeo.read_from_las(OUT + ".las", additional_dimensions={"distances": "d"})
        out = {"xyz": back.cloud, "d": back.additional_dimensions["d"].ravel()}""",
    "CloudCompare names": """
        e1, e2 = py4dgeo.read_from_xyz(T1, T2)
        d, u = py4dgeo.CloudCompareM3C2(epochs=(e1, e2), corepoints=e1.cloud[::7], normalscale=[3.0],
                                        searchscale=2.0, searchdepth=3.0).run()
        out = {"distance": d}""",
    "ICP, then M3C2": """
        reference, epoch = py4dgeo.read_from_xyz(R1, R2)
        reference.calculate_normals(radius=1.0)
        epoch.calculate_normals(radius=1.0)
        trafo = py4dgeo.point_to_plane_icp(reference, epoch)
        epoch.transform(trafo)
        d, u = py4dgeo.M3C2(epochs=(reference, epoch), corepoints=reference.cloud[::50], normal_radii=[1.0],
                            cyl_radius=0.5, max_distance=1.0).run()
        out = {"moved": epoch.cloud, "distance": d}""",
    "M3C2-EP": """
        # Equal angular sigmas, and sigma_range_ppm (m3c2kit's; py4dgeo reads no such key) at
        # 1e3 sqrt(sigma_range): py4dgeo's range and angle defects then change nothing.
        position = {"sigma_range": 0.004, "sigma_range_ppm": 1e3 * 0.004 ** 0.5, "sigma_scan": 3e-4, "sigma_yaw": 3e-4}
        sps = {str(k + 1): {"origin": list(o), **position} for k, o in enumerate(EP["scanners"])}
        e1, e2 = py4dgeo.read_from_xyz(E1, E2, additional_dimensions={3: "scanpos_id"})
        e1.scanpos_info = sps
        e2.scanpos_info = sps
        m = py4dgeo.M3C2EP(epochs=(e1, e2), corepoints=e1.cloud[::100], normal_radii=[0.5], cyl_radius=0.25,
                           max_distance=0.3, Cxx=EP["cxx"], tfM=np.eye(3, 4), refPointMov=np.zeros(3))
        d, u, cov = m.run()
        out = {"distance": d, "size": np.abs(d), "lod": u["lodetection"], "cov2": cov["cov2"]}""",
    "catching py4dgeo's error": """
        Py4DGeoError = py4dgeo.util.Py4DGeoError  # where py4dgeo defines it
        e1, e2 = py4dgeo.read_from_xyz(T1, T2)
        try:
            py4dgeo.M3C2(epochs=(e1, e2), corepoints=e1.cloud[::7], normal_radii=[1.5]).run()
            caught = "nothing raised"
        except Py4DGeoError:
            caught = "Py4DGeoError"
        out = {"caught": np.array([caught])}""",
}

RUNNER = """
import json, sys, traceback
import numpy as np
{import_line}
T1, T2, S1, S2, R1, R2, E1, E2, OUT = {paths!r}
EP = np.load(E1 + ".npz")
results = {{}}
for name, body in {scripts!r}.items():
    try:
        scope = dict(globals())
        exec(body, scope)
        np.savez(OUT + "_" + str(len(results)) + ".npz", **scope["out"])
        results[name] = {{"ok": True, "file": OUT + "_" + str(len(results)) + ".npz"}}
    except Exception as e:
        results[name] = {{"ok": False, "error": type(e).__name__ + ": " + str(e).splitlines()[0][:160]}}
print(json.dumps(results))
"""


def _surface(folder: Path) -> tuple[str, str]:
    rng = np.random.default_rng(3)
    xy = rng.uniform(0, 10, (3000, 2))
    ref = np.column_stack([xy, 0.3 * xy[:, 0] + rng.normal(0, 0.01, 3000)])
    cmp_ = ref + [0, 0, 0.05] + rng.normal(0, 0.01, (3000, 3))
    paths = str(folder / "s1.xyz"), str(folder / "s2.xyz")
    np.savetxt(paths[0], ref)
    np.savetxt(paths[1], cmp_)
    return paths


def _terrain(folder: Path) -> tuple[str, str]:
    """The registration tests' rough terrain (tests/python/registration/terrain.py), the second
    epoch moved by a known rigid motion."""
    sys.path.insert(0, str(REPO / "tests" / "python" / "registration"))
    import terrain
    paths = str(folder / "r1.xyz"), str(folder / "r2.xyz")
    for path, cloud in zip(paths, terrain.epochs(20000, seed=1, change=0.0)):
        np.savetxt(path, cloud)
    return paths


def _scans(folder: Path) -> tuple[str, str]:
    """Two epochs of validation/uncertainty_sim.py's scanned surface: x y z scan-position id, and
    the scanners and the simulator's alignment covariance in e1.xyz.npz."""
    sys.path.insert(0, str(REPO / "validation"))
    import uncertainty_sim as sim
    sim.POINTS_PER_SCAN = 2000
    rng = np.random.default_rng(16)
    paths = str(folder / "e1.xyz"), str(folder / "e2.xyz")
    for path in paths:
        xyz, ids = sim.scan(rng)
        np.savetxt(path, np.column_stack([xyz, ids]))
    np.savez(paths[0] + ".npz", scanners=sim.SCANNERS, cxx=sim.alignment_covariance())
    return paths


def _run(python: str, import_line: str, folder: Path, tag: str, env: dict) -> dict:
    paths = (str(TUTORIAL / "plane_horizontal_t1.xyz"), str(TUTORIAL / "plane_horizontal_t2.xyz"),
             *_surface(folder), *_terrain(folder), *_scans(folder), str(folder / tag))
    scripts = {k: textwrap.dedent(v) for k, v in SCRIPTS.items()}
    code = RUNNER.format(import_line=import_line, paths=paths, scripts=scripts)
    out = subprocess.run([python, "-c", code], capture_output=True, text=True, env=env, cwd=folder)
    if out.returncode != 0:
        raise SystemExit(f"{tag}: {out.stderr[-2000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def _difference(a: dict, b: dict) -> str:
    za, zb = np.load(a["file"]), np.load(b["file"])
    parts = []
    for key in za.files:
        x, y = za[key], zb[key]
        if x.dtype.kind in "US" or y.dtype.kind in "US":
            parts.append(f"{key} {'same' if np.array_equal(x, y) else f'{x.tolist()} vs {y.tolist()}'}")
            continue
        x, y = x.astype(float), y.astype(float)
        if x.shape != y.shape:
            parts.append(f"{key} shapes {x.shape} vs {y.shape}")
            continue
        both = np.isfinite(x) & np.isfinite(y)
        worst = float(np.max(np.abs(x[both] - y[both]))) if both.any() else 0.0
        parts.append(f"{key} max |diff| {worst:.2g}, NaN {int((~np.isfinite(x)).sum())}/{int((~np.isfinite(y)).sum())}")
    return "; ".join(parts)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--py4dgeo-python", required=True, help="a Python with py4dgeo 1.2.0 installed")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        theirs = _run(args.py4dgeo_python, "import py4dgeo", folder, "py4dgeo", dict(os.environ))
        env = dict(os.environ, PYTHONPATH=str(REPO / "python"))
        ours = _run(sys.executable, "import m3c2kit.compat.py4dgeo as py4dgeo", folder, "ours", env)
        print(f"{'script':34s} | py4dgeo 1.2.0 | compat | numbers")
        for name in SCRIPTS:
            a, b = theirs[name], ours[name]
            shown = lambda r: "ran" if r["ok"] else r["error"]  # noqa: E731
            numbers = _difference(a, b) if a["ok"] and b["ok"] else ""
            print(f"{name:34s} | {shown(a)[:60]} | {shown(b)[:60]} | {numbers}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
