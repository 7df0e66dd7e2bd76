"""A seeded synthetic M3C2 time series with planted changes (docs/validation.md, "Time series"):
a rough surface, a slowly deepening landslide, short-lived accumulation objects, per-epoch noise
and one epoch with a registration offset. Each epoch is an independent random sampling of the
surface (as repeated laser scans are), written as .npy; epoch 0 is the reference itself.

    python validation/series_synthetic.py OUT_DIR [--reduced]

Nothing here is part of the package. `planted(...)` gives each planted object's space-time
extent on a set of core points, the ground truth of the IoU check."""
from __future__ import annotations

import argparse
import json
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class Blob:
    """A flat-topped pile of `height` (radius in metres), appearing over `rise` epochs from
    `onset` and removed at `removal` (gone from that epoch on)."""
    cx: float
    cy: float
    radius: float
    height: float
    onset: int
    removal: int
    rise: int = 2


@dataclass(frozen=True)
class Landslide:
    """An ellipse whose surface drops by `drop` at `onset` (the failure), then keeps sinking by
    `rate` per epoch (the creep) to the end of the series."""
    cx: float
    cy: float
    ax: float
    ay: float
    drop: float
    rate: float
    onset: int


@dataclass(frozen=True)
class Scenario:
    extent: float = 40.0          # square side, metres
    density: float = 64.0         # points per square metre per epoch
    epochs: int = 100
    noise: float = 0.01           # per-point Gaussian noise, metres
    offset_epoch: int = 57        # this epoch is shifted by `offset` in z (a registration error)
    offset: float = 0.04
    seed: int = 20210301
    landslide: Landslide = Landslide(12.0, 28.0, 7.0, 5.0, 0.08, 0.003, 15)
    # Short-lived piles. Each starts after the first half window (12 epochs) and lasts longer
    # than half the rest of the series on one side of it: the change-point search of 4D-OBC
    # needs both to place its first break (docs/validation.md, "Time series").
    blobs: tuple = (Blob(30.0, 30.0, 4.0, 0.3, 14, 44), Blob(28.0, 10.0, 4.0, 0.25, 62, 90),
                    Blob(10.0, 9.0, 3.5, 0.35, 40, 76))

    @staticmethod
    def reduced() -> "Scenario":
        """The CI version: a 24 m square at 16 points per square metre, the same 100 epochs."""
        return Scenario(extent=24.0, density=16.0, landslide=Landslide(7.0, 17.0, 4.5, 3.5, 0.08, 0.003, 15),
                        blobs=(Blob(18.0, 18.0, 3.0, 0.3, 14, 44), Blob(17.5, 6.0, 3.0, 0.25, 62, 90)))


def rough(x, y):
    """The surface: metre-scale relief and decimetre roughness."""
    return (0.6 * np.sin(0.21 * x) * np.cos(0.17 * y) + 0.15 * np.sin(1.3 * x + 0.7 * y)
            + 0.05 * np.sin(3.1 * x - 2.3 * y))


def change(s: Scenario, x, y, t: int) -> np.ndarray:
    """The planted change in z at (x, y) and epoch t (the registration offset excluded)."""
    dz = np.zeros_like(x)
    ls = s.landslide
    inside = ((x - ls.cx) / ls.ax) ** 2 + ((y - ls.cy) / ls.ay) ** 2 <= 1.0
    if t >= ls.onset:
        dz -= np.where(inside, ls.drop + ls.rate * (t - ls.onset), 0.0)
    for b in s.blobs:
        if b.onset <= t < b.removal:
            grown = min(1.0, (t - b.onset + 1) / b.rise)
            dz += np.where(np.hypot(x - b.cx, y - b.cy) <= b.radius, b.height * grown, 0.0)
    return dz


def epoch_cloud(s: Scenario, t: int) -> np.ndarray:
    rng = np.random.default_rng([s.seed, t])
    n = int(s.extent * s.extent * s.density)
    x, y = rng.uniform(0, s.extent, n), rng.uniform(0, s.extent, n)
    z = rough(x, y) + change(s, x, y, t) + rng.normal(0.0, s.noise, n)
    if t == s.offset_epoch:
        z = z + s.offset
    return np.column_stack([x, y, z])


def write(s: Scenario, out: Path) -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for t in range(s.epochs):
        p = out / f"epoch_{t:03d}.npy"
        np.save(p, epoch_cloud(s, t))
        paths.append(p)
    (out / "scenario.json").write_text(json.dumps(asdict(s), indent=1))
    # The epochs' times: hourly from 2024-01-01 (a list file, as `m3c2 series` reads it).
    lines = [f"{p.name}, {np.datetime64('2024-01-01T00:00') + np.timedelta64(t, 'h')}\n" for t, p in enumerate(paths)]
    (out / "epochs.txt").write_text("".join(lines))
    return paths


def planted(s: Scenario, core: np.ndarray, n_epochs: int) -> list[tuple[str, np.ndarray]]:
    """Each planted object's space-time extent on the core points: a (core, epoch) bool mask,
    True where the core point's (x, y) lies in the object and the change is under way."""
    x, y = core[:, 0], core[:, 1]
    out = []
    ls = s.landslide
    inside = ((x - ls.cx) / ls.ax) ** 2 + ((y - ls.cy) / ls.ay) ** 2 <= 1.0
    mask = np.zeros((len(core), n_epochs), bool)
    mask[inside, ls.onset:] = True
    out.append(("landslide", mask))
    for k, b in enumerate(s.blobs):
        mask = np.zeros((len(core), n_epochs), bool)
        mask[np.hypot(x - b.cx, y - b.cy) <= b.radius, b.onset:b.removal] = True
        out.append((f"accumulation {k}", mask))
    return out


def iou(a: np.ndarray, b: np.ndarray) -> float:
    union = np.count_nonzero(a | b)
    return np.count_nonzero(a & b) / union if union else 0.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--reduced", action="store_true")
    args = ap.parse_args()
    s = Scenario.reduced() if args.reduced else Scenario()
    write(s, args.out)
    print(f"{args.out}: {s.epochs} epochs of {int(s.extent ** 2 * s.density)} points")


if __name__ == "__main__":
    main()
