"""The in-memory run's memory estimate (m3c2::IndexMemory, memory.estimate_memory) against the
peak a real run reaches: an upper estimate, and not a loose one (docs/errors.md, "Memory")."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from child_env import child_env

# A surface (2D) or a volume (3D, vegetation) of n points at a spacing, with D a multiple of it:
# the finest cell is D / 16 rounded to a power of two, and the nodes per point (what varies most
# with the cloud) peak at about a point per cell.
CHILD = r"""
import json, sys
import numpy as np
from m3c2kit import api
from m3c2kit.run import memory
from m3c2kit.settings import build_params

def status(key):
    with open("/proc/self/status") as f:
        return next(int(l.split()[1]) * 1024 for l in f if l.startswith(key + ":"))

n, dims, spacing, d_ratio = int(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
reorder, source = sys.argv[5] == "1", sys.argv[6]
rng = np.random.default_rng(11)
side = spacing * n ** (1 / dims)
ref = np.empty((n, 3))
ref[:, :dims] = rng.uniform(0, side, (n, dims))
if dims == 2:
    ref[:, 2] = 0.2 * np.sin(ref[:, 0] / 3) + rng.normal(0, 0.02, n)
cmp_ = ref + rng.normal(0, 0.02, ref.shape)
core = np.ascontiguousarray(ref[::10])
params = dict(normal_scale=d_ratio * spacing, projection_scale=4 * spacing, max_depth=1.0, threads=2,
              normal_source=source)
api.compare(ref[:1000], cmp_[:1000], core[:100], **params)  # libraries loaded, pools started
with open("/proc/self/clear_refs", "w") as f:
    f.write("5")  # VmHWM starts afresh from the resident size now
before = status("VmRSS")
api.compare(ref, cmp_, core, reorder_inputs=reorder, **params)
estimate = memory.estimate_memory(n, n, len(core), build_params(**params), reorder_inputs=reorder)
print(json.dumps(dict(peak=status("VmHWM") - before, estimate=estimate)))
"""


def peak_and_estimate(n: int, dims: int, spacing: float, d_ratio: float, reorder: bool, source: str) -> dict:
    args = [str(v) for v in (n, dims, spacing, d_ratio, "1" if reorder else "0", source)]
    proc = subprocess.run([sys.executable, "-W", "ignore", "-c", CHILD, *args], capture_output=True, text=True,
                          env=child_env(), timeout=600)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _can_reset_the_peak() -> bool:
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


# The copy and the in-place ordering, moments on one cloud and on both, and the densities with the
# most nodes per point (a surface's at 2.5 points per cell, a volume's at 1.4 per cell) and few.
CASES = [(1_000_000, 2, 0.1, 40, False, "reference"), (1_000_000, 2, 0.1, 10, False, "reference"),
         (1_000_000, 2, 0.1, 40, True, "reference"), (1_000_000, 2, 0.1, 20, True, "mean"),
         (1_000_000, 3, 0.1, 14, False, "reference")]


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/status").exists() or not _can_reset_the_peak(),
                    reason="needs /proc (Linux) and its clear_refs for the peak")
@pytest.mark.parametrize("n, dims, spacing, d_ratio, reorder, source", CASES)
def test_the_estimate_bounds_the_peak_closely(n, dims, spacing, d_ratio, reorder, source):
    r = peak_and_estimate(n, dims, spacing, d_ratio, reorder, source)
    per_point = {k: round(v / (2 * n), 1) for k, v in r.items()}
    assert r["peak"] <= r["estimate"], f"the run took more than estimated (B per input point): {per_point}"
    assert r["estimate"] <= 3 * r["peak"], f"the estimate is loose (B per input point): {per_point}"
