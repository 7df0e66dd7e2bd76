"""The training samples in each classifier's plane with its boundary (Brodu & Lague 2012, Fig. 5)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..analysis.common import figure_format
from ..base.errors import UsageError
from ..io.atomic import atomic_output
from .model import Classifier

MAX_DRAWN = 20_000  # points per class drawn (seeded subsample beyond)


def plot_training(clf: Classifier, X: np.ndarray, y: np.ndarray, path: Path, seed: int = 0) -> None:
    """Draws the training samples in each binary classifier's plane into `path`, atomically."""
    fig = training_figure(clf, X, y, seed)
    with atomic_output(path) as tmp:
        save_training_figure(fig, tmp, path)


def save_training_figure(fig, target, named: Path) -> None:
    """Saves `fig` at `target` in the format `named`'s extension says, and closes it."""
    import matplotlib.pyplot as plt
    try:
        fig.savefig(target, format=figure_format(named, extra="classify"), dpi=110)
    finally:
        plt.close(fig)


def training_figure(clf: Classifier, X: np.ndarray, y: np.ndarray, seed: int = 0):
    """The figure of plot_training, drawn but not saved."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise UsageError("--plot needs matplotlib: pip install 'm3c2kit[classify]'") from None
    rng = np.random.default_rng(seed)
    n = len(clf.binaries)
    fig, axes = plt.subplots(1, n, figsize=(6.5 * n, 5.5), squeeze=False)
    for ax, b in zip(axes[0], clf.binaries):
        P = {}
        for c in (b.class1, b.class2):
            idx = np.flatnonzero(y == c)
            if len(idx) > MAX_DRAWN:
                idx = np.sort(rng.choice(idx, MAX_DRAWN, replace=False))
            P[c] = b.project(X[idx])
        for c, colour in ((b.class1, "tab:brown"), (b.class2, "tab:green")):
            ax.scatter(P[c][:, 0], P[c][:, 1], s=2, alpha=0.3, color=colour, label=f"{c} ({np.count_nonzero(y == c)})",
                       rasterized=True)
        allp = np.vstack(list(P.values()))
        lo, hi = np.percentile(allp, 0.5, axis=0), np.percentile(allp, 99.5, axis=0)
        pad = 0.1 * (hi - lo) + 1e-9
        ax.set_xlim(lo[0] - pad[0], hi[0] + pad[0])
        ax.set_ylim(lo[1] - pad[1], hi[1] + pad[1])
        path_pts = np.asarray(b.path)
        ends = [path_pts[0] + 1e3 * (path_pts[0] - path_pts[1]), *path_pts,
                path_pts[-1] + 1e3 * (path_pts[-1] - path_pts[-2])]
        ends = np.array(ends)
        ax.plot(ends[:, 0], ends[:, 1], "k-", lw=1.5, label="boundary")
        ba = b.info.get("balanced_accuracy")
        ax.set_title(f"{b.class1} / {b.class2}" + (f": balanced accuracy {100 * ba:.2f} % (training)" if ba else ""))
        ax.set_xlabel("axis 1 (discriminant, within-class std units)")
        ax.set_ylabel("axis 2")
        ax.legend(loc="best", markerscale=5, fontsize=8)
    fig.suptitle("CANUPO training samples, scales " + ", ".join(f"{s:g}" for s in clf.scales))
    fig.tight_layout()
    return fig
