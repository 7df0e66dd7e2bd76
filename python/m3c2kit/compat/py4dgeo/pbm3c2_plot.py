"""py4dgeo's PBM3C2.visualize_correspondences: the paired segments' points (epoch 0 blue, epoch 1
red), their centroids and an arrow from each reference centroid to its pair's, labelled with the
distance (matplotlib, 3D)."""
from __future__ import annotations

import numpy as np

from ...base.errors import UsageError

__all__ = ["plot_correspondences"]


def _sample(frame, alg, epoch0_segment_id, use_original_ids, show_all, num_samples):
    if epoch0_segment_id is not None:
        column = "epoch0_original_id" if use_original_ids and "epoch0_original_id" in frame else "epoch0_segment_id"
        chosen = frame[frame[column] == epoch0_segment_id]
        if chosen.empty:
            raise ValueError(f"Segment ID {epoch0_segment_id} not found in correspondences.")
        return chosen, f"PBM3C2 Correspondence for Segment ID {epoch0_segment_id}"
    if show_all or len(frame) <= num_samples:
        return frame, f"PBM3C2 Correspondences (showing all {len(frame)})"
    rows = np.random.choice(len(frame), num_samples, replace=False)  # py4dgeo's draw (the global seed)
    return frame.iloc[rows], f"PBM3C2 Correspondences (showing {num_samples} of {len(frame)})"


def plot_correspondences(alg, epoch0_segment_id, use_original_ids, show_all, num_samples, figsize, elev, azim):
    frame = alg.correspondences
    if frame is None or frame.empty:
        raise ValueError("No correspondences found. Run run() first.")
    try:
        import matplotlib.pyplot as plt
    except ImportError:
        raise UsageError("visualize_correspondences needs matplotlib: pip install 'm3c2kit[report]'") from None
    chosen, title = _sample(frame, alg, epoch0_segment_id, use_original_ids, show_all, num_samples)
    fig = plt.figure(figsize=figsize)
    ax = fig.add_subplot(111, projection="3d")
    metrics = (alg.epoch0_segment_metrics, alg.epoch1_segment_metrics)
    for k, (_, row) in enumerate(chosen.iterrows()):
        ids = (row["epoch0_segment_id"], row["epoch1_segment_id"])
        centres = []
        for side, (segments, colour, dark) in enumerate(((alg.epoch0_segments, "blue", "darkblue"),
                                                         (alg.epoch1_segments, "red", "darkred"))):
            points = segments[ids[side]]["points"]
            ax.scatter(points[:, 0], points[:, 1], points[:, 2], c=colour, s=5, alpha=0.3,
                       label=f"Epoch {side}" if k == 0 else None)
            centre = metrics[side].loc[ids[side], ["cog_x", "cog_y", "cog_z"]].to_numpy(dtype=float)
            ax.scatter(*centre, c=dark, s=100, marker="o", edgecolors="black", linewidths=2)
            centres.append(centre)
        step = centres[1] - centres[0]
        ax.quiver(*centres[0], *step, color="green", linewidth=2)
        middle = centres[0] + step / 2
        ax.text(*middle, f"{row['distance']:.3f}m", fontsize=8, color="green", weight="bold")
    ax.set_xlabel("X [m]")
    ax.set_ylabel("Y [m]")
    ax.set_zlabel("Z [m]")
    ax.set_title(title, fontsize=14, weight="bold")
    ax.legend(loc="upper right")
    ax.view_init(elev=elev, azim=azim)
    return fig, ax
