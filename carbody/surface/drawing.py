"""Drawing of a region's skeleton: boundary, optimal pairs and skeleton line (paper Fig. 17–18)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from carbody.surface.body import RegionSkeleton


def draw_skeleton(sk: RegionSkeleton, path: str | Path, title: str = "") -> Path:
    """Write a PNG of the projected boundary (black, samples as dots with outward normals),
    the optimal pairs (red, numbered in the order found) and the skeleton line (blue dashes).

    Args:
        sk: a region's skeleton (:func:`carbody.surface.body.region_skeleton`).
        path: PNG file to write.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    s = sk.samples
    fig, ax = plt.subplots(figsize=(9, 6.5))
    ring = np.vstack([s.dense2d, s.dense2d[:1]])
    ax.plot(ring[:, 0], ring[:, 1], color="black", lw=1.4, label="boundary")
    ax.plot(s.points2d[:, 0], s.points2d[:, 1], "o", color="black", ms=2.5)
    ax.quiver(s.points2d[:, 0], s.points2d[:, 1], s.normals2d[:, 0], s.normals2d[:, 1], color="0.6",
              scale=40, width=0.002)
    for k, p in enumerate(sk.pairs):
        a, b = s.points2d[p.i], s.points2d[p.j]
        ax.plot([a[0], b[0]], [a[1], b[1]], color="#d62728", lw=1.0, label="optimal pairs" if k == 0 else None)
        m = (a + b) / 2
        ax.annotate(str(k + 1), m, fontsize=7, color="#d62728", xytext=(2, 2), textcoords="offset points")
    ax.plot(sk.line[:, 0], sk.line[:, 1], "--", color="#1f4e9c", lw=1.8, label="skeleton")
    ax.plot(sk.line[[0, -1], 0], sk.line[[0, -1], 1], "s", color="#1f4e9c", ms=5)
    ax.set_aspect("equal")
    ax.grid(alpha=0.25)
    ax.legend(loc="best", fontsize=8)
    ax.set_title(title or f"{sk.outline.name}: {len(sk.pairs)} optimal pairs (normalised units, clockwise)")
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=90)
    plt.close(fig)
    return out
