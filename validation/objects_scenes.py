"""Seeded synthetic scenes for 4D objects-by-change (docs/series.md, "Analysis"): core points on
a grid, their M3C2 distances stored directly as a (core point, epoch) array, five events above
the noise and a scene with nothing above it. The truth of validation/objects_truth.py and of
tests/python/series/test_objects_truth.py; tests/cpp/test_objects_truth.cpp builds the same
events in C++ (its own noise).

Events (each a footprint and a change in time, 100 epochs):
- deposit: +10 cm over epochs 30-32, kept;
- erosion strip: -8 cm over epochs 40-44 on a 6 m x 2 m strip, kept;
- bump: +12 cm at epoch 18, back to 0 at epoch 72 (a change that appears, then reverses; it lasts
  longer than the rest of the series after it, or the L1 change-point search finds no break);
- subsidence: -4 cm linearly over epochs 44-55 (12 epochs), kept;
- rockfall: -12 cm in one epoch (50), kept.
Noise: Gaussian, 6 mm per core point and epoch (the smallest event is 6.7 sigma)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

EPOCHS = 100
SPACING = 0.5  # metres between core points
SIDE = 32      # core points per row: a 16 m x 16 m grid
NOISE = 0.006  # metres


@dataclass(frozen=True)
class Event:
    name: str
    first: int           # the first changed epoch
    last: int            # the last epoch of the change's extent (EPOCHS - 1 when kept)
    profile: tuple       # (epoch, change) knots, linear between, constant outside

    def change(self, epochs: int) -> np.ndarray:
        t, v = zip(*self.profile)
        return np.interp(np.arange(epochs), t, v)


EVENTS = (
    Event("deposit", 30, EPOCHS - 1, ((29, 0.0), (32, 0.10))),
    Event("erosion strip", 40, EPOCHS - 1, ((39, 0.0), (44, -0.08))),
    Event("bump", 18, 72, ((17, 0.0), (18, 0.12), (71, 0.12), (72, 0.0))),
    Event("subsidence", 45, EPOCHS - 1, ((44, 0.0), (56, -0.04))),
    Event("rockfall", 50, EPOCHS - 1, ((49, 0.0), (50, -0.12))),
)


def core_points() -> np.ndarray:
    """The grid, row-major (x fastest), z = 0."""
    y, x = np.mgrid[0:SIDE, 0:SIDE] * SPACING
    return np.column_stack([x.ravel(), y.ravel(), np.zeros(SIDE * SIDE)])


def footprints(core: np.ndarray) -> dict[str, np.ndarray]:
    """Each event's core points (boolean masks): discs, and the strip."""
    x, y = core[:, 0], core[:, 1]

    def disc(cx, cy, r):
        return (x - cx) ** 2 + (y - cy) ** 2 <= r * r

    return {"deposit": disc(4.0, 4.0, 2.0), "erosion strip": (x >= 9.0) & (x <= 15.0) & (y >= 1.0) & (y <= 3.0),
            "bump": disc(4.0, 11.5, 2.2), "subsidence": disc(11.5, 8.0, 2.2), "rockfall": disc(11.5, 13.5, 1.8)}


def scene(seed: int, events: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """(core points, distances): distances[c, t] is the change at core point c and epoch t plus
    the noise; events=False: the noise alone."""
    core = core_points()
    rng = np.random.default_rng(seed)
    d = NOISE * rng.standard_normal((len(core), EPOCHS))
    if events:
        masks = footprints(core)
        for e in EVENTS:
            d[masks[e.name]] += e.change(EPOCHS)
    return core, d


def truth(core: np.ndarray) -> list[tuple[str, np.ndarray]]:
    """Each event's extent in space and time: its footprint x [first - 1, last] (the epoch
    before the change is where it starts from)."""
    masks = footprints(core)
    out = []
    for e in EVENTS:
        m = np.zeros((len(core), EPOCHS), bool)
        m[np.ix_(masks[e.name], np.arange(e.first - 1, e.last + 1))] = True
        out.append((e.name, m))
    return out


def extent(n_core: int, members, start: int, end: int) -> np.ndarray:
    """An object's extent: its members x [start, end]."""
    m = np.zeros((n_core, EPOCHS), bool)
    m[np.asarray(members, dtype=int), start:end + 1] = True
    return m


def iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two extents (cells of core point x epoch)."""
    union = np.logical_or(a, b).sum()
    return float(np.logical_and(a, b).sum() / union) if union else 0.0


def score(found: list[np.ndarray], core: np.ndarray, threshold: float = 0.5) -> dict:
    """Per event the best IoU of an object, recall (events with IoU >= threshold), precision
    (objects with IoU >= threshold to some event) and the objects matching none."""
    events = truth(core)
    best = {name: max((iou(m, f) for f in found), default=0.0) for name, m in events}
    matched = [max((iou(m, f) for _, m in events), default=0.0) >= threshold for f in found]
    return {"best": best, "recall": sum(v >= threshold for v in best.values()) / len(events),
            "precision": (sum(matched) / len(found)) if found else 1.0, "false": len(found) - sum(matched)}
