"""Folds: a region whose surface turns back over itself, or whose outline crosses itself in 3D.

The arc-length layout (:mod:`carbody.surface.arc_layout`) surfaces any region whose curves
close, so a valid sewn shell no longer proves a sound body: a junction dragged far (the roof's
front corner pulled back over the roof, a B-pillar top pushed below the belt) gives faces that
fold over like a creased sheet, or an outline that runs through itself, and BRepCheck still
finds nothing wrong. Two measures, on the Bezier nets (numpy, no OCCT):

* **folded area share**: on a grid of each face, the area element S_u x S_v is compared with the
  face's own mean normal (its vector area); where they point apart, the face has turned over.
  The share is that area over the region's whole area (left half). A bicubic face of a region
  bends less than 90° (its sides turn at most 50°, ribs are added where they would), so a sound
  face has none; the templates' wheel arches fold a sliver near the sill (up to 0.7 %), the
  faces of a region pulled past itself 2–25 %. A region folds when its share passes
  :data:`~carbody.tolerances.FOLD_AREA_SHARE` (2 %). (A region bent back smoothly over several
  faces, a U-turn with no crease, is not a fold by this measure.)
* **outline crossing**: two curves of the region's loop that share no junction pass within
  :data:`~carbody.tolerances.DEGENERATE_LENGTH_REL` of the loop's length of each other (the
  tolerance at which two junctions are one): no surface bounded by that loop can be a sheet.

:func:`region_folds` gives both per region; :func:`fold_message` says a fold in one line naming
the region and the curves it lies on.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from carbody.surface.control_net import FacePatch
from carbody.surface.quality import _bern, _dbern
from carbody.surface.regions import RegionOutline, bezier_points
from carbody.tolerances import DEGENERATE_LENGTH_REL, FOLD_AREA_SHARE
from carbody.topology import Topology, load_topology

#: Grid points per face side for the folded area.
FOLD_GRID = 25

#: Curves a fold message names at most (the most folded first).
MESSAGE_CURVES = 4

#: Samples per curve for the outline crossing search (refined by a local minimisation).
CROSSING_SAMPLES = 48


@dataclass
class RegionFold:
    """How one region folds.

    Attributes:
        region: the region.
        folded_area_share: share of the region's area (0..1) whose faces have turned over.
        fold_curves: wireframe curves (names) bounding the faces that turn over, most folded first.
        crossing: the two curves of the outline that pass through each other, or None.
        crossing_mm: how close they pass (mm), or None.
    """

    region: str
    folded_area_share: float
    fold_curves: list[str] = field(default_factory=list)
    crossing: tuple[str, str] | None = None
    crossing_mm: float | None = None

    @property
    def folds(self) -> bool:
        """Whether the region folds (its outline crosses itself, or too much of it turns over)."""
        return self.crossing is not None or self.folded_area_share > FOLD_AREA_SHARE


def face_folded_area(nets: np.ndarray, n: int = FOLD_GRID) -> tuple[np.ndarray, np.ndarray]:
    """(folded area, whole area) of bicubic faces (F, 4, 4, 3) or one (4, 4, 3): (F,) mm^2 each
    (trapezoid rule on an n x n grid)."""
    nets = np.asarray(nets, float).reshape(-1, 4, 4, 3)
    t = np.linspace(0.0, 1.0, n)
    b, db = _bern(t), _dbern(t)
    su = np.einsum("bj,fajd->fabd", b, np.einsum("ai,fijd->fajd", db, nets))
    sv = np.einsum("bj,fajd->fabd", db, np.einsum("ai,fijd->fajd", b, nets))
    j = np.cross(su, sv).reshape(len(nets), -1, 3)
    w = np.full(n, 1.0 / (n - 1))
    w[[0, -1]] /= 2
    weight = np.outer(w, w).ravel()
    mean = np.einsum("fmd,m->fd", j, weight)
    size = np.linalg.norm(j, axis=2) * weight
    turned = np.einsum("fmd,fd->fm", j, mean) < 0
    folded = (size * turned).sum(axis=1)
    # a face creased exactly in half has no mean normal to turn against: half of it is turned
    balanced = np.linalg.norm(mean, axis=1) <= 1e-9 * size.sum(axis=1)
    return np.where(balanced, size.sum(axis=1) / 2, folded), size.sum(axis=1)


def _curve_names(face: FacePatch, topology: Topology) -> list[str]:
    return [topology.curves[ref.curve].name for ref in face.sides.values() if ref is not None]


def folded_area(faces: list[FacePatch], topology: Topology | None = None) -> tuple[float, list[str]]:
    """(share of the faces' area that has turned over, the curves of the folding faces, most
    folded first)."""
    topo = topology or load_topology()
    if not faces:
        return 0.0, []
    folded, whole = face_folded_area(np.array([f.net for f in faces]))
    by_curve: dict[str, float] = {}
    for face, f in zip(faces, folded):
        if f > 0:
            for name in _curve_names(face, topo):
                by_curve[name] = by_curve.get(name, 0.0) + float(f)
    share = float(folded.sum() / whole.sum()) if whole.sum() > 0 else 0.0
    return share, sorted(by_curve, key=lambda k: -by_curve[k])


def outline_crossing(control_points: np.ndarray, outline: RegionOutline,
                     topology: Topology | None = None) -> tuple[tuple[str, str], float] | None:
    """The two curves of a region's loop that share no junction yet meet (within
    DEGENERATE_LENGTH_REL of the loop's length), and how close they pass (mm); None if none do."""
    topo = topology or load_topology()
    region = topo.region(outline.name)
    curves = [topo.curves[ci] for ci, _ in region.loop]
    t = np.linspace(0.0, 1.0, CROSSING_SAMPLES)
    poles = np.array([control_points[4 * c.index:4 * c.index + 4] for c in curves])
    pts = np.einsum("ti,cid->ctd", np.stack([(1 - t) ** 3, 3 * (1 - t) ** 2 * t, 3 * (1 - t) * t**2, t**3], 1), poles)
    steps = np.linalg.norm(np.diff(pts, axis=1), axis=2)
    tol = DEGENERATE_LENGTH_REL * float(steps.sum())
    lo, hi = pts.min(axis=1) - tol, pts.max(axis=1) + tol
    best = None
    for a in range(len(curves)):
        for b in range(a + 1, len(curves)):
            if {curves[a].start, curves[a].end} & {curves[b].start, curves[b].end}:
                continue
            if np.any(lo[a] > hi[b]) or np.any(lo[b] > hi[a]):
                continue  # their bounding boxes are apart
            d = np.linalg.norm(pts[a][:, None] - pts[b][None], axis=2)
            i, j = np.unravel_index(int(np.argmin(d)), d.shape)
            if d[i, j] > steps[a].max() + steps[b].max() + tol:
                continue  # the samples are further apart than the curves between them could come
            best = _closer(best, poles, curves, a, b, t[i], t[j], float(d[i, j]), tol)
    return best


def _closer(best, poles, curves, a, b, s0, u0, d0, tol):
    """The closest approach of curves a and b near samples (s0, u0), if within tol and closer
    than ``best``: a grid search on windows shrinking around the best pair (numpy only)."""
    s, u, closest, half = s0, u0, d0, 1.0 / (CROSSING_SAMPLES - 1)
    for _ in range(12):
        ss = np.clip(np.linspace(s - half, s + half, 17), 0.0, 1.0)
        uu = np.clip(np.linspace(u - half, u + half, 17), 0.0, 1.0)
        d = np.linalg.norm(bezier_points(poles[a], ss)[:, None] - bezier_points(poles[b], uu)[None], axis=2)
        i, j = np.unravel_index(int(np.argmin(d)), d.shape)
        s, u, closest, half = ss[i], uu[j], min(closest, float(d[i, j])), half / 4
    if closest <= tol and (best is None or closest < best[1]):
        return (curves[a].name, curves[b].name), closest
    return best


def region_folds(control_points: np.ndarray, outlines: list[RegionOutline], faces_by_region: dict[str, list[FacePatch]],
                 topology: Topology | None = None) -> list[RegionFold]:
    """:class:`RegionFold` of every region (left half), in the outlines' order."""
    topo = topology or load_topology()
    out = []
    for outline in outlines:
        share, names = folded_area(faces_by_region[outline.name], topo)
        crossing = outline_crossing(control_points, outline, topo)
        out.append(RegionFold(outline.name, share, names, crossing[0] if crossing else None,
                              crossing[1] if crossing else None))
    return out


def fold_message(fold: RegionFold) -> str:
    """One line: the region, how it folds, and the curves it folds at."""
    if fold.crossing is not None:
        a, b = fold.crossing
        return (f"region {fold.region} folds: its outline crosses itself in 3D (curves {a} and {b} "
                f"pass {fold.crossing_mm:.2g} mm apart)")
    names = fold.fold_curves[:MESSAGE_CURVES]
    more = len(fold.fold_curves) - len(names)
    return (f"region {fold.region} folds: {100 * fold.folded_area_share:.1f} % of its area turns back over "
            f"itself (more than {100 * FOLD_AREA_SHARE:g} %), most at curves {', '.join(names)}"
            + (f" (and {more} more)" if more > 0 else ""))
