"""CANUPO ground / not-ground classification on real airborne lidar (AHN, issue 18).

Trains on one AHN tile (classes 2 = ground, 1 = other and 6 = building = not ground), applies the
classifier to the other tile, and writes docs/validation/canupo-ahn.md (the section that
docs/validation.md includes: confusion matrices, balanced accuracies) with its pictures
docs/validation/canupo-ahn-*.png. Run from the repository with the package installed (and the
[classify] extra):

    python validation/canupo_ahn.py

Both directions are run (A -> B and B -> A). The scales are the command line's default (4 to 32
times the point spacing of the training tile), chosen before looking at any result.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

import m3c2kit
from m3c2kit.classify import classify
from m3c2kit.cli.classify import default_scales
from m3c2kit.classify.labels import labels_from_field
from m3c2kit.classify.plot import plot_training
from m3c2kit.classify.train import train_with_samples

REPO = Path(__file__).resolve().parents[1]
AHN = REPO.parent / "shared" / "data" / "readers" / "ahn"
TILES = {"A": "ahn_2386_9702.laz", "B": "ahn_2397_9705.laz"}
VALUES = {"2": "ground", "1": "not ground", "6": "not ground"}
OUT = REPO / "docs" / "validation"


def load(tile):
    cloud = m3c2kit.read(AHN / TILES[tile])
    labels = labels_from_field(cloud, "classification", AHN / TILES[tile], VALUES)
    return cloud, labels


def confusion(truth, predicted, classes):
    return np.array([[int(np.count_nonzero((truth == t) & (predicted == p))) for p in classes] for t in classes])


def map_picture(xyz, truth, predicted, title, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    kinds = [("ground, right", (truth == "ground") & (predicted == "ground"), "#b08850"),
             ("not ground, right", (truth != "ground") & (predicted != "ground"), "#3a9a3a"),
             ("ground called not ground", (truth == "ground") & (predicted != "ground"), "#d62728"),
             ("not ground called ground", (truth != "ground") & (predicted == "ground"), "#1f3fff")]
    fig, ax = plt.subplots(figsize=(7.5, 7))
    for name, mask, colour in kinds:
        ax.scatter(xyz[mask, 0] - xyz[:, 0].min(), xyz[mask, 1] - xyz[:, 1].min(), s=1.2, color=colour,
                   label=f"{name} ({int(mask.sum())})", rasterized=True)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m, from the tile's west edge)")
    ax.set_ylabel("y (m)")
    ax.set_title(title)
    ax.legend(loc="upper right", markerscale=6, fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run(train_tile, test_tile, lines):
    cloud, labels = load(train_tile)
    scales = default_scales(cloud.xyz)
    t0 = time.perf_counter()
    clf, X, y = train_with_samples([(cloud.xyz, labels)], scales, max_per_class=None)
    t_train = time.perf_counter() - t0
    plot_training(clf, X, y, OUT / f"canupo-ahn-train-{train_tile}.png")
    test, truth = load(test_tile)
    t0 = time.perf_counter()
    p = classify(clf, test.xyz)
    t_apply = time.perf_counter() - t0
    predicted = p.labels(clf, missing="(no features)")
    classes = ["ground", "not ground"]
    m = confusion(truth, predicted, classes)
    recall = m.diagonal() / m.sum(axis=1)
    ba = recall.mean()
    no_features = int(np.count_nonzero(p.index < 0))
    map_picture(test.xyz, truth, predicted, f"tile {test_tile} classified by the classifier of tile {train_tile}: "
                f"balanced accuracy {100 * ba:.2f} %", OUT / f"canupo-ahn-{train_tile}-to-{test_tile}.png")
    b = clf.binaries[0]
    lines += [f"### Trained on tile {train_tile} ({TILES[train_tile]}), applied to tile {test_tile} "
              f"({TILES[test_tile]})\n",
              f"Scales (diameters, m): {', '.join(f'{s:g}' for s in clf.scales)}; training points: "
              + ", ".join(f"{c} {n}" for c, n in clf.info['training']['points'].items())
              + f"; training balanced accuracy {100 * clf.info['training']['balanced_accuracy']:.2f} %; "
              f"boundary {b.info['boundary_angle_deg']:+.0f} degrees from the discriminant axis. "
              f"Training took {t_train:.1f} s, applying {t_apply:.1f} s ({len(test.xyz)} points).\n",
              "| truth \\ predicted | ground | not ground | recall |", "|---|---:|---:|---:|"]
    for k, c in enumerate(classes):
        lines.append(f"| {c} | {m[k, 0]} | {m[k, 1]} | {100 * recall[k]:.2f} % |")
    lines += ["", f"**Balanced accuracy: {100 * ba:.2f} %** (points without features: {no_features}, "
              "counted as wrong).", "",
              "Each scale alone (balanced accuracy of its two descriptor values on the training tile): "
              + ", ".join(f"{s['scale']:g} m {100 * s['balanced_accuracy']:.1f} %"
                          for s in sorted(b.info["scale_power"], key=lambda s: s["scale"])) + ".", "",
              f"![tile {test_tile} classified](validation/canupo-ahn-{train_tile}-to-{test_tile}.png)",
              f"![training samples of tile {train_tile} in the classifier's plane](validation/canupo-ahn-train-{train_tile}.png)",
              ""]
    return ba, m


def main():
    OUT.mkdir(parents=True, exist_ok=True)
    lines = ["<!-- Generated by validation/canupo_ahn.py; do not edit by hand: rerun it. -->", "",
             "Real airborne lidar: the two AHN tiles of `shared/data/readers/ahn` (Dutch national lidar, "
             "~44k points each, 50 m x 50 m, urban: ground, trees and buildings). Labels from the files' "
             "classification: 2 = ground; 1 (other: vegetation, street furniture) and 6 (buildings) = "
             "not ground. CANUPO separates by local dimensionality alone: flat roofs are 2D like the "
             "ground, so buildings are the expected confusion (below, in blue). Reproduce with "
             "`python validation/canupo_ahn.py` (package installed with the [classify] extra).", ""]
    results = [run("A", "B", lines), run("B", "A", lines)]
    lines.append("Summary: balanced accuracy " + ", ".join(
        f"{name} {100 * ba:.2f} %" for name, (ba, _) in zip(("A -> B", "B -> A"), results)) + ".")
    (OUT / "canupo-ahn.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
