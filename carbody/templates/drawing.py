"""Four-view drawing of a wireframe with its keypoints labelled (the paper's Fig. 2 and Fig. 6)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from carbody.topology import Topology, load_topology
from carbody.wireframe import sample_curves

#: (title, horizontal axis, vertical axis, draw both halves) per view; an axis is (coordinate,
#: sign): −1 runs it the other way (the axis inverted, its labels the car frame's own).
VIEWS = (
    ("side (left)", (1, 1.0), (2, 1.0), False),
    ("front", (0, 1.0), (2, 1.0), True),
    ("top", (1, 1.0), (0, -1.0), True),
    ("rear", (0, -1.0), (2, 1.0), True),
)


def draw_four_views(control_points: np.ndarray, path: str | Path, title: str = "",
                    topology: Topology | None = None, keypoint_sd_mm: np.ndarray | None = None) -> Path:
    """Write a PNG with the front, side, top and rear views and the 35 keypoints labelled
    (:func:`four_views_figure`), whole or not at all.

    Returns:
        the written path.
    """
    import matplotlib.pyplot as plt

    from carbody.occ.step_curves import atomic_write

    fig = four_views_figure(control_points, title, topology, keypoint_sd_mm)
    try:
        return atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=90))
    finally:
        plt.close(fig)


def four_views_figure(control_points: np.ndarray, title: str = "", topology: Topology | None = None,
                      keypoint_sd_mm: np.ndarray | None = None):
    """The matplotlib figure of :func:`draw_four_views`: each view's axes labelled in the car
    frame's own mm (a view seen the other way runs its axis backwards, it does not negate it).

    Args:
        control_points: (280, 3) float, mm, car frame (left half).
        title: heading of the drawing (the car's name).
        keypoint_sd_mm: (35, 3) float or None: each keypoint's standard deviation per axis (a
            fit's :meth:`~carbody.fit.result.FitResult.keypoint_sd_mm`): the keypoints are
            coloured by their expected 3D error (a colour bar gives the scale) and each gets its
            1σ ellipse in every view — which of the car's dimensions the photo fixed and which
            are the library's guess.
    Returns:
        the figure (close it with ``matplotlib.pyplot.close``).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Ellipse

    topo = topology or load_topology()
    if keypoint_sd_mm is not None:
        expected = np.linalg.norm(keypoint_sd_mm, axis=1)
        cmap = plt.get_cmap("RdYlGn_r")
        norm = matplotlib.colors.Normalize(0.0, max(float(expected.max()), 1.0))
    curves = sample_curves(control_points)
    mirror = curves * np.array([-1.0, 1.0, 1.0])
    kp = control_points[topo.keypoint_point_indices]
    fig = plt.figure(figsize=(16, 9.5))
    grid = fig.add_gridspec(2, 3, width_ratios=[2.2, 1.0, 0.9])
    axes = [fig.add_subplot(grid[0, 0]), fig.add_subplot(grid[0, 1]),
            fig.add_subplot(grid[1, 0]), fig.add_subplot(grid[1, 1])]
    for ax, (name, (hi, hs), (vi, vs), both) in zip(axes, VIEWS):
        for group, colour in ((curves, "#1f4e9c"), (mirror, "#9fb3d6")) if both else ((curves, "#1f4e9c"),):
            for c in group:
                ax.plot(c[:, hi], c[:, vi], color=colour, lw=1.2)
        for i, (k, p) in enumerate(zip(topo.keypoints, kp)):
            facing = (name.startswith("front") and p[1] < 0.5 * control_points[:, 1].max() / 2) or \
                     (name.startswith("rear") and p[1] > 0.5 * control_points[:, 1].max()) or \
                     name.startswith(("side", "top"))
            if not facing:
                continue
            colour = "#d62728"
            if keypoint_sd_mm is not None:
                colour = cmap(norm(expected[i]))
                ax.add_patch(Ellipse((p[hi], p[vi]), 2 * keypoint_sd_mm[i, hi], 2 * keypoint_sd_mm[i, vi],
                                     facecolor=colour, edgecolor=colour, alpha=0.25, lw=0.8))
            ax.plot(p[hi], p[vi], "o", color=colour, ms=5 if keypoint_sd_mm is not None else 3.5)
            ax.annotate(str(k.id), (p[hi], p[vi]), fontsize=7, color="#d62728",
                        xytext=(2, 2), textcoords="offset points")
        if hs < 0:
            ax.invert_xaxis()
        if vs < 0:
            ax.invert_yaxis()
        ax.set_title(name)
        ax.set_aspect("equal")
        ax.grid(alpha=0.25)
        ax.tick_params(labelsize=7)
    legend = fig.add_subplot(grid[:, 2])
    legend.axis("off")
    if keypoint_sd_mm is not None:
        bar = fig.colorbar(matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap), ax=legend, location="bottom",
                           fraction=0.05, pad=0.02)
        bar.set_label("expected 3D error of the keypoint (mm)")
    legend.text(0, 1, "\n".join(f"{k.id:2d}  {k.name}" for k in topo.keypoints),
                va="top", family="monospace", fontsize=8.5)
    note = ", keypoints coloured by their expected error, 1σ ellipses" if keypoint_sd_mm is not None else ""
    fig.suptitle(f"{title}  (mm; front wheel centre at y = 0, wheel centres at z = 0{note})")
    fig.tight_layout()
    return fig
